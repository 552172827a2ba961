#include "frontend/frame_exporter.h"

#include <QDir>
#include <QImage>
#include <QStandardPaths>

#include "frontend/view_widget.h"

namespace costume::frontend {

FrameExporter::FrameExporter(ViewWidget& view, QObject* parent) : QObject(parent), view_(view) {
  // Queued: grabFramebuffer renders again, which must not happen inside paintGL.
  connect(&view_, &ViewWidget::frameDrawn, this, [this] { WriteFrame(); }, Qt::QueuedConnection);
  connect(&ffmpeg_, &QProcess::finished, this, [this](int code) {
    emit videoDone(code == 0 ? "video written: " + QDir(folder_).filePath("animation.mp4")
                             : QString("ffmpeg failed (exit %1)").arg(code));
  });
}

QString FrameExporter::FfmpegPath() { return QStandardPaths::findExecutable("ffmpeg"); }

bool FrameExporter::Start(const QString& folder, QString* error) {
  if (!QDir().mkpath(folder)) {
    if (error) *error = "cannot create " + folder;
    return false;
  }
  folder_ = folder;
  written_ = 0;
  recording_ = true;
  return true;
}

void FrameExporter::WriteFrame() {
  if (!recording_) return;
  const QString path = QDir(folder_).filePath(QString("frame_%1.png").arg(written_, 5, 10, QChar('0')));
  if (view_.grabFramebuffer().save(path, "PNG")) ++written_;
}

QString FrameExporter::Finish() {
  if (!recording_) return "not recording";
  recording_ = false;
  QString message = QString("%1 frames written to %2").arg(written_).arg(folder_);
  const QString ffmpeg = FfmpegPath();
  if (ffmpeg.isEmpty()) return message + " (no ffmpeg on PATH: no video)";
  if (written_ == 0) return message;
  ffmpeg_.setWorkingDirectory(folder_);
  ffmpeg_.start(ffmpeg, {"-y", "-loglevel", "error", "-framerate", "60", "-i", "frame_%05d.png",
                         "-pix_fmt", "yuv420p", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                         "animation.mp4"});
  return message + "; encoding animation.mp4 with ffmpeg";
}

bool FrameExporter::Screenshot(ViewWidget& view, const QString& path) {
  return view.grabFramebuffer().save(path, "PNG");
}

}  // namespace costume::frontend
