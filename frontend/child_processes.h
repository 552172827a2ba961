#pragma once
/// @file
/// The processes the GUI owns: the simulation server and the haptic server, started as child
/// QProcesses and stopped (SIGTERM, then SIGKILL after 3 s) when the window closes. The
/// device menu connects a device by starting `costume_haptic_server --device <x>` and
/// disconnects it by stopping that process; a device whose SDK this build lacks makes the
/// server exit at once with its error, which is reported (deviceError). Thumbnails the
/// catalogue lacks are rendered by `costume-catalog thumbnails` in a third child, so that
/// draping garments for their pictures never stalls the window.

#include <QObject>
#include <QProcess>
#include <QString>
#include <QStringList>
#include <optional>

#include <Eigen/Core>

namespace costume::frontend {

/// Where the programs are and what they are told.
struct ServerOptions {
  QString bin_dir;           ///< build directory holding sim_core/app/, haptic_server/ and
                             ///< catalog/
  QString lcm_url;           ///< passed as --lcm-url
  bool allow_network = false;  ///< passed as --allow-network (the GUI's own flag)
  QString builtin = "garment";  ///< --builtin for the simulation server (when scene_file is empty)
  QString scene_file;        ///< --scene for the simulation server
  QString trajectory;        ///< --trajectory for the simulated device
  QString catalog_url;       ///< $COSTUME_CATALOG for the children ("" = their default, the
                             ///< same catalog::DefaultCatalogUrl() the GUI's lists use)
  double radius = 0.05;      ///< --radius of the haptic grab [m]
  /// The workspace of a physical device (OpenHaptics, CyberGrasp), whose tip reports in its
  /// own frame around its own origin: --scale (scene metres per device metre) and --offset,
  /// the scene point its origin stands for (the cloth's centre, else it would reach only the
  /// floor between the avatar's feet). The mouse and the simulated device report scene
  /// positions and get neither.
  double workspace_scale = 1.0;
  std::optional<Eigen::Vector3d> workspace_centre;
  bool editing = false;      ///< start the simulation server in mode B
};

/// The import folder (`costume-catalog import --root`) for files a designer picked in a
/// file dialog: the deepest folder holding them all, raised for a MakeHuman garment (.mhclo)
/// to two levels above its own folder, where MakeHuman's asset layout keeps the body it is
/// fitted to (clothes/<name>/<name>.mhclo beside body/base.obj).
QString ImportRoot(const QStringList& files);

/// `costume-catalog import`'s arguments for `files` picked as entries of `kind` ("avatar",
/// "garment", "animation"): --kind, --root (ImportRoot), then the files. Garments: a .obj,
/// .mhskel or .mhw picked beside MakeHuman garments is the body they are fitted to
/// (--makehuman-body, --makehuman-skeleton, --makehuman-weights), not an entry.
QStringList ImportArguments(const QString& kind, const QStringList& files);

/// The device menu's devices, as `--device` names them.
QStringList DeviceNames();
/// Whether `device` reports in a frame of its own (a workspace scale and centre apply).
bool IsPhysicalDevice(const QString& device);

class ChildProcesses : public QObject {
  Q_OBJECT

 public:
  explicit ChildProcesses(ServerOptions options, QObject* parent = nullptr);
  ~ChildProcesses() override;

  /// The programs' paths.
  QString SimServerPath() const;
  QString HapticServerPath() const;
  QString CatalogProgramPath() const;
  /// The simulation server's arguments.
  QStringList SimServerArguments() const;
  /// The haptic server's arguments for `device` ("simulated", "mouse", "openhaptics",
  /// "cybergrasp").
  QStringList HapticServerArguments(const QString& device) const;

  /// Starts the simulation server (once). False with the reason in `*error`.
  bool StartSimServer(QString* error = nullptr);
  /// Starts the haptic server for `device`, stopping a running one first.
  bool ConnectDevice(const QString& device, QString* error = nullptr);
  /// Stops the haptic server.
  void DisconnectDevice();
  /// Starts `costume-catalog thumbnails` on the catalogue unless it is already running;
  /// thumbnailsMade follows when it ends. False with the reason in `*error`.
  bool MakeMissingThumbnails(QString* error = nullptr);
  /// Starts `costume-catalog import <arguments>` (ImportArguments) on the catalogue (one
  /// import at a time), which checks each file, renders its thumbnail and stores all or
  /// none; its progress lines come as output("catalogue", …) and importFinished follows.
  /// False with the reason in `*error`.
  bool Import(const QStringList& arguments, QString* error = nullptr);
  bool importing() const { return import_.state() != QProcess::NotRunning; }
  /// The children's environment: the GUI's, with COSTUME_CATALOG set to `catalog_url` when
  /// one was given. The URL goes there, not on a command line, because a PostgreSQL URL may
  /// hold a password that `ps` would show every user of the machine.
  QProcessEnvironment ChildEnvironment() const;
  /// Stops both (SIGTERM, waits up to 3 s each, then SIGKILL).
  void StopAll();

  /// Whether each child is running; the device last connected; the options (mutable: the
  /// radius field updates them for the next connect).
  bool sim_running() const { return sim_.state() != QProcess::NotRunning; }
  bool device_running() const { return haptic_.state() != QProcess::NotRunning; }
  const QString& device() const { return device_; }
  ServerOptions& options() { return options_; }

 signals:
  /// A line the simulation server or haptic server printed (stdout or stderr).
  void output(const QString& process, const QString& line);
  /// The haptic server exited on its own (SDK missing, device not found) with its message.
  void deviceError(const QString& device, const QString& message);
  /// The haptic server started / stopped.
  void deviceChanged(const QString& device, bool connected);
  /// The simulation server ended on its own (not through StopAll): `how` is "exit code 1" or
  /// "crashed".
  void simServerExited(const QString& how);
  /// The thumbnails child ended (0: every thumbnail it could make is stored).
  void thumbnailsMade(int exit_code);
  /// The import child ended: 0 when every file was imported (otherwise none was), with
  /// everything it printed.
  void importFinished(int exit_code, const QString& output);

 private:
  void Forward(QProcess& process, const QString& name);
  static void Stop(QProcess& process);

  ServerOptions options_;
  QProcess sim_;
  QProcess haptic_;
  QProcess thumbnails_;
  QProcess import_;
  QString device_;
  QString haptic_output_;
  QString import_output_;
  bool stopping_haptic_ = false;
  bool stopping_sim_ = false;
};

}  // namespace costume::frontend
