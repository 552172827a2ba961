#include "frontend/child_processes.h"

#include <sys/prctl.h>

#include <QDir>
#include <algorithm>
#include <csignal>
#include <QFileInfo>

namespace costume::frontend {

QStringList DeviceNames() { return {"simulated", "mouse", "openhaptics", "cybergrasp"}; }

bool IsPhysicalDevice(const QString& device) {
  return device == "openhaptics" || device == "cybergrasp";
}

ChildProcesses::ChildProcesses(ServerOptions options, QObject* parent)
    : QObject(parent), options_(std::move(options)) {
  // A child gets SIGTERM when the GUI dies, however it dies (even SIGKILL): no server is left
  // running without the window that owns it.
  for (QProcess* process : {&sim_, &haptic_, &thumbnails_, &import_}) {
    process->setChildProcessModifier([] { prctl(PR_SET_PDEATHSIG, SIGTERM); });
  }
  Forward(sim_, "sim_server");
  Forward(haptic_, "haptic_server");
  Forward(thumbnails_, "catalogue");
  Forward(import_, "catalogue");
  connect(&import_, &QProcess::finished, this, [this](int code, QProcess::ExitStatus status) {
    emit importFinished(status == QProcess::CrashExit ? -1 : code, import_output_);
  });
  connect(&thumbnails_, &QProcess::finished, this, [this](int code, QProcess::ExitStatus status) {
    emit thumbnailsMade(status == QProcess::CrashExit ? -1 : code);
  });
  connect(&sim_, &QProcess::finished, this, [this](int code, QProcess::ExitStatus status) {
    if (stopping_sim_) return;  // the window closing: nothing to report
    emit simServerExited(status == QProcess::CrashExit ? QString("crashed")
                                                       : QString("exit code %1").arg(code));
  });
  connect(&haptic_, &QProcess::finished, this, [this](int code, QProcess::ExitStatus status) {
    const QString device = device_;
    emit deviceChanged(device, false);
    if (stopping_haptic_) return;
    // Exited on its own: a device it could not open, an SDK this build lacks (exit 1 or 2).
    QString message = haptic_output_.trimmed();
    if (message.isEmpty()) {
      message = QString("costume_haptic_server exited (%1 %2)")
                    .arg(status == QProcess::CrashExit ? "crash" : "code")
                    .arg(code);
    }
    emit deviceError(device, message);
  });
  connect(&haptic_, &QProcess::errorOccurred, this, [this](QProcess::ProcessError error) {
    if (error == QProcess::FailedToStart) {
      emit deviceError(device_, "cannot start " + HapticServerPath() + ": " + haptic_.errorString());
    }
  });
}

ChildProcesses::~ChildProcesses() { StopAll(); }

void ChildProcesses::Forward(QProcess& process, const QString& name) {
  process.setProcessChannelMode(QProcess::MergedChannels);
  connect(&process, &QProcess::readyRead, this, [this, &process, name] {
    while (process.canReadLine()) {
      const QString line = QString::fromUtf8(process.readLine()).trimmed();
      if (&process == &haptic_) haptic_output_ += line + "\n";
      if (&process == &import_) import_output_ += line + "\n";
      emit output(name, line);
    }
  });
}

QString ChildProcesses::SimServerPath() const {
  return QDir(options_.bin_dir).filePath("sim_core/app/costume_sim_server");
}

QString ChildProcesses::HapticServerPath() const {
  return QDir(options_.bin_dir).filePath("haptic_server/costume_haptic_server");
}

QString ChildProcesses::CatalogProgramPath() const {
  return QDir(options_.bin_dir).filePath("catalog/costume-catalog");
}

QStringList ChildProcesses::SimServerArguments() const {
  QStringList args;
  if (options_.scene_file.isEmpty()) {
    args << "--builtin" << options_.builtin;
  } else {
    args << "--scene" << options_.scene_file;
  }
  if (!options_.lcm_url.isEmpty()) args << "--lcm-url" << options_.lcm_url;
  if (options_.allow_network) args << "--allow-network";  // else they refuse the GUI's URL
  if (options_.editing) args << "--editing";
  return args;
}

QStringList ChildProcesses::HapticServerArguments(const QString& device) const {
  QStringList args{"--device", device, "--radius", QString::number(options_.radius)};
  if (device == "simulated") args << "--trajectory" << options_.trajectory;
  if (IsPhysicalDevice(device)) {
    args << "--scale" << QString::number(options_.workspace_scale);
    if (options_.workspace_centre) {
      const Eigen::Vector3d& c = *options_.workspace_centre;
      args << "--offset" << QString::number(c.x()) << QString::number(c.y())
           << QString::number(c.z());
    }
  }
  if (!options_.lcm_url.isEmpty()) args << "--lcm-url" << options_.lcm_url;
  if (options_.allow_network) args << "--allow-network";
  return args;
}

bool ChildProcesses::StartSimServer(QString* error) {
  if (sim_running()) return true;
  if (!QFileInfo(SimServerPath()).isExecutable()) {
    if (error) *error = "no simulation server at " + SimServerPath() + " (build it first)";
    return false;
  }
  stopping_sim_ = false;
  sim_.setProcessEnvironment(ChildEnvironment());
  sim_.start(SimServerPath(), SimServerArguments());
  if (!sim_.waitForStarted(5000)) {
    if (error) *error = "cannot start " + SimServerPath() + ": " + sim_.errorString();
    return false;
  }
  return true;
}

bool ChildProcesses::ConnectDevice(const QString& device, QString* error) {
  DisconnectDevice();
  if (!DeviceNames().contains(device)) {
    if (error) *error = "unknown device '" + device + "': allowed " + DeviceNames().join(", ");
    return false;
  }
  if (!QFileInfo(HapticServerPath()).isExecutable()) {
    if (error) *error = "no haptic server at " + HapticServerPath() + " (build it first)";
    return false;
  }
  device_ = device;
  haptic_output_.clear();
  stopping_haptic_ = false;
  haptic_.start(HapticServerPath(), HapticServerArguments(device));
  if (!haptic_.waitForStarted(5000)) {
    if (error) *error = "cannot start " + HapticServerPath() + ": " + haptic_.errorString();
    return false;
  }
  emit deviceChanged(device, true);
  return true;
}

QProcessEnvironment ChildProcesses::ChildEnvironment() const {
  QProcessEnvironment environment = QProcessEnvironment::systemEnvironment();
  if (!options_.catalog_url.isEmpty()) environment.insert("COSTUME_CATALOG", options_.catalog_url);
  return environment;
}

bool ChildProcesses::MakeMissingThumbnails(QString* error) {
  if (thumbnails_.state() != QProcess::NotRunning) return true;
  if (!QFileInfo(CatalogProgramPath()).isExecutable()) {
    if (error) *error = "no catalogue program at " + CatalogProgramPath() + " (build it first)";
    return false;
  }
  thumbnails_.setProcessEnvironment(ChildEnvironment());
  thumbnails_.start(CatalogProgramPath(), {"thumbnails"});
  if (!thumbnails_.waitForStarted(5000)) {
    if (error) *error = "cannot start " + CatalogProgramPath() + ": " + thumbnails_.errorString();
    return false;
  }
  return true;
}

bool ChildProcesses::Import(const QStringList& arguments, QString* error) {
  if (importing()) {
    if (error) *error = "an import is still running";
    return false;
  }
  if (!QFileInfo(CatalogProgramPath()).isExecutable()) {
    if (error) *error = "no catalogue program at " + CatalogProgramPath() + " (build it first)";
    return false;
  }
  import_output_.clear();
  import_.setProcessEnvironment(ChildEnvironment());
  import_.start(CatalogProgramPath(), QStringList{"import"} + arguments);
  if (!import_.waitForStarted(5000)) {
    if (error) *error = "cannot start " + CatalogProgramPath() + ": " + import_.errorString();
    return false;
  }
  return true;
}

QString ImportRoot(const QStringList& files) {
  // Paths as text: QDir::cdUp refuses a parent that does not exist.
  auto parent = [](const QString& path) { return QDir::cleanPath(path + "/.."); };
  QString root;
  for (const QString& file : files) {
    QString path = QFileInfo(file).absolutePath();
    if (file.endsWith(".mhclo", Qt::CaseInsensitive)) path = parent(parent(path));
    if (root.isEmpty()) {
      root = path;
      continue;
    }
    // The deepest folder holding both: shorten the root until `path` lies inside it.
    while (root != "/" && path != root && !path.startsWith(root + '/')) root = parent(root);
  }
  return root;
}

QStringList ImportArguments(const QString& kind, const QStringList& files) {
  QStringList options{"--kind", kind, "--root", ImportRoot(files)};
  QStringList entries;
  const bool makehuman_garments =
      kind == "garment" &&
      std::any_of(files.begin(), files.end(),
                  [](const QString& f) { return f.endsWith(".mhclo", Qt::CaseInsensitive); });
  for (const QString& file : files) {
    const QString suffix = QFileInfo(file).suffix().toLower();
    if (makehuman_garments && suffix == "obj") {
      options << "--makehuman-body" << file;
    } else if (makehuman_garments && suffix == "mhskel") {
      options << "--makehuman-skeleton" << file;
    } else if (makehuman_garments && suffix == "mhw") {
      options << "--makehuman-weights" << file;
    } else {
      entries << file;
    }
  }
  // "--": a file named like an option stays a file.
  return options + QStringList{"--"} + entries;
}

void ChildProcesses::Stop(QProcess& process) {
  if (process.state() == QProcess::NotRunning) return;
  process.terminate();  // SIGTERM: both servers stop cleanly (the grab fades out first)
  if (!process.waitForFinished(3000)) {
    process.kill();
    process.waitForFinished(1000);
  }
}

void ChildProcesses::DisconnectDevice() {
  stopping_haptic_ = true;
  Stop(haptic_);
}

void ChildProcesses::StopAll() {
  DisconnectDevice();
  stopping_sim_ = true;
  Stop(sim_);
  Stop(thumbnails_);
  Stop(import_);
}

}  // namespace costume::frontend
