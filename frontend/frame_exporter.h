#pragma once
/// @file
/// Export of an animation: while recording, every received frame the view draws is read back
/// from its framebuffer (QOpenGLWidget::grabFramebuffer) and written as
/// <folder>/frame_00000.png, frame_00001.png, ...; on Finish, when `ffmpeg` is on PATH, the
/// frames are encoded into <folder>/animation.mp4 (H.264, 60 fps, yuv420p).

#include <QObject>
#include <QProcess>
#include <QString>

namespace costume::frontend {

class ViewWidget;

class FrameExporter : public QObject {
  Q_OBJECT

 public:
  /// `view` must outlive the exporter.
  explicit FrameExporter(ViewWidget& view, QObject* parent = nullptr);

  /// Starts writing frames into `folder` (created). False with the reason when it cannot be
  /// created.
  bool Start(const QString& folder, QString* error = nullptr);
  /// Stops recording; starts ffmpeg when it is on PATH. Returns what was done, for the
  /// status bar.
  QString Finish();
  /// Writes the view's current image as one PNG (a screenshot). False when it cannot.
  static bool Screenshot(ViewWidget& view, const QString& path);

  bool recording() const { return recording_; }
  int frames_written() const { return written_; }
  /// Path of ffmpeg, empty when it is not on PATH.
  static QString FfmpegPath();

 signals:
  void videoDone(const QString& message);

 private:
  void WriteFrame();

  ViewWidget& view_;
  QString folder_;
  bool recording_ = false;
  int written_ = 0;
  QProcess ffmpeg_;
};

}  // namespace costume::frontend
