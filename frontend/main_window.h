#pragma once
/// @file
/// The Costume Designer main window (paper §7.2): the three thumbnail lists (costumes,
/// avatars, animations), the fabric, solver and posture panels, playback, the mode switch,
/// the editing controls (selection radius, eliminate stretch energy, undo, redo, save as a new
/// version), the device menu, the 3D view and the status bar. Every control publishes its
/// command through CommandSender; what the processes publish arrives through BusLink's
/// queued signals (docs/frontend.md).

#include <QActionGroup>
#include <QDoubleSpinBox>
#include <QElapsedTimer>
#include <QHash>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QMainWindow>
#include <QPlainTextEdit>
#include <QPushButton>
#include <QRadioButton>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "bus/message_bus.h"
#include "frontend/bus_link.h"
#include "frontend/catalog_source.h"
#include "frontend/child_processes.h"
#include "frontend/cloth_frame_assembler.h"
#include "frontend/command_sender.h"
#include "frontend/control_panels.h"
#include "frontend/frame_exporter.h"
#include "frontend/scene_mirror.h"
#include "frontend/view_widget.h"

namespace costume::frontend {

/// How the window starts.
struct FrontendOptions {
  /// The scene the simulation server runs, mirrored locally (scene_mirror.h).
  std::string builtin = "garment";
  std::string scene_file;
  /// Start the simulation server as a child process.
  bool start_sim_server = false;
  /// Device to connect at start ("" = none): starts the haptic server.
  QString device;
  ServerOptions servers;
};

/// "sim 59.9 Hz · 12 it · 8.1 ms (max 11.0) · frame 120, 2.00 s · playing · editing ·
/// undo 1" from a simulation server status.
QString FormatSimStatus(const costume_lcm::status& status);
/// "haptic 1000 Hz · tick 0.02 ms · p99 1019 µs" from a haptic server status.
QString FormatHapticStatus(const costume_lcm::status& status);
/// True for the haptic server's once-a-second figures it sends as warnings ("loop: ...",
/// "safety: ..."): shown as the status label's tooltip, not as warnings.
bool IsPeriodicFigure(const std::string& warning);

class MainWindow : public QMainWindow {
  Q_OBJECT

 public:
  /// `bus` (not owned) carries everything; the window subscribes on it at once. Nothing is
  /// received until StartBusThread (the program) or link().Poll (tests, memq://). Throws
  /// sim::InputError when the scene cannot be mirrored.
  MainWindow(bus::MessageBus& bus, FrontendOptions options, std::unique_ptr<CatalogSource> catalog,
             QWidget* parent = nullptr);
  ~MainWindow() override;

  /// Receives on the window's own LCM thread from now on.
  void StartBusThread();
  /// Starts the child processes the options ask for; errors go to the message log.
  void StartChildren();

  BusLink& link() { return *link_; }
  CommandSender& sender() { return *sender_; }
  ViewWidget& view() { return *view_; }
  SceneMirror& mirror() { return *mirror_; }
  /// The mirror of a requested load the server has not shown yet (null when none).
  const SceneMirror* pending_mirror() const { return pending_mirror_.get(); }
  ChildProcesses& children() { return *children_; }
  FrameExporter& exporter() { return *exporter_; }
  const ClothFrameAssembler& assembler() const { return assembler_; }

  // Controls, exposed for the tests (they drive them as a user would).
  QListWidget* list(EntryKind kind) const { return lists_[static_cast<int>(kind)]; }
  QPushButton* load_button(EntryKind kind) const { return load_buttons_[static_cast<int>(kind)]; }
  MaterialPanel* material_panel() const { return material_; }
  SolverPanel* solver_panel() const { return solver_; }
  CollisionPanel* collision_panel() const { return collision_; }
  PosturePanel* posture_panel() const { return posture_; }
  QAction* play_action() const { return play_; }
  QAction* pause_action() const { return pause_; }
  QAction* stop_action() const { return stop_; }
  QRadioButton* animation_mode() const { return animation_mode_; }
  QRadioButton* editing_mode() const { return editing_mode_; }
  QDoubleSpinBox* radius_box() const { return radius_; }
  QPushButton* stretch_button() const { return stretch_; }
  QPushButton* undo_button() const { return undo_; }
  QPushButton* redo_button() const { return redo_; }
  QLineEdit* version_label() const { return version_label_; }
  QPushButton* save_button() const { return save_; }
  QAction* device_action(const QString& device) const;
  QAction* connect_action() const { return connect_device_; }
  QAction* start_server_action() const { return start_server_; }
  QAction* disconnect_action() const { return disconnect_device_; }
  QLabel* sim_label() const { return sim_label_; }
  QLabel* haptic_label() const { return haptic_label_; }
  QLabel* device_label() const { return device_label_; }
  QLabel* warning_label() const { return warning_label_; }
  QLabel* force_label() const { return force_label_; }
  QPlainTextEdit* message_log() const { return log_; }
  /// Some listed entry shows the "no picture yet" stand-in.
  bool lists_lack_thumbnails() const { return lists_lack_thumbnails_; }
  /// The last whole frame received, if any.
  const std::optional<ClothFrame>& last_frame() const { return last_frame_; }
  /// Where "eliminate stretch energy" acts [m]: the last mouse grab point, else the device
  /// cursor, else the cloth's centroid.
  Eigen::Vector3d StretchCentre() const;
  /// The mean of the cloth's particles as the view last showed them (origin without cloth).
  Eigen::Vector3d ClothCentroid() const;
  /// Starts the haptic server for `device`, a physical one with its workspace centred on the
  /// cloth at the scale field's value; errors go to the status bar.
  void ConnectDevice(const QString& device);
  /// Imports `files` (picked in File → Import …) as entries of `kind` through a child
  /// `costume-catalog import`: progress in the message log, then the lists filled again, or
  /// the refusal (nothing imported) on the status bar.
  void ImportFiles(EntryKind kind, const QStringList& files);
  QAction* import_action(EntryKind kind) const { return import_actions_[static_cast<int>(kind)]; }
  /// Removes the listed entry `name` of `kind` from the catalogue (the lists' context menu
  /// asks first) and fills the lists again; false, with the reason as the warning, when it
  /// is built in or not listed.
  bool RemoveEntry(EntryKind kind, const QString& name);

 public slots:
  void OnClothChunk(const costume_lcm::cloth_frame& chunk);
  void OnSimStatus(const costume_lcm::status& status);
  void OnHapticStatus(const costume_lcm::status& status);
  void OnDeviceState(const costume_lcm::device_state& state);
  /// Shows the force the device renders (what a stylus would feel with the mouse) [N].
  void OnFeedback(const costume_lcm::feedback& message);
  /// Appends a line to the message log (warnings, process output).
  void Log(const QString& line);
  /// Logs the line and shows it on the status bar: what the designer must act on.
  void Warn(const QString& line);

 protected:
  void closeEvent(QCloseEvent* event) override;

 private:
  QWidget* BuildLists();
  QWidget* BuildEditing();
  void BuildMenus();
  void BuildStatusBar();
  /// Lists the catalogue's entries again; notes whether some lack a thumbnail.
  void FillLists();
  /// Starts the simulation server after it stopped; the view follows its start scene.
  void RestartSimServer();
  /// Lists again and has the missing thumbnails rendered (after a saved version, on F5).
  void RefreshCatalogue();
  /// Picks (and shows) in its list the last entry an import's `output` says it stored.
  void PickImported(const QString& output);
  /// The context menu of a list's entry at `at`: remove it, after a confirmation.
  void OfferRemoval(EntryKind kind, const QPoint& at);
  /// After a child `costume-catalog import` (ImportFiles): the lists filled again, or its
  /// refusal as the warning.
  void ShowImportResult(int code, const QString& output);
  /// Starts the child that renders the thumbnails the lists lack (a database only); the
  /// lists are filled again when it ends.
  void MakeMissingThumbnails();
  void LoadSelected(EntryKind kind);
  /// Builds the mirror of the scene a LOAD_* asks for (scene_mirror.h); it replaces the view's
  /// mirror when the server's frames show the new scene (AdoptPendingMirror) and is dropped
  /// when the server refuses the load (a "command LOAD_…" warning).
  void MirrorLoad(EntryKind kind, const CatalogItem& item);
  /// Switches to the pending mirror when `frame` is of it: its particle count, and either a
  /// rebuilt simulation (frame number went down) or a count the current mirror does not have.
  bool AdoptPendingMirror(const ClothFrame& frame);
  /// Shows the mirrored scene's solver and collision settings on their tabs: after a load
  /// they are the server's (a first avatar brings the default collision settings).
  void SyncSettingsPanels();
  /// `change` on the mirror and on the pending one, as the server applies it to its scene.
  void ForEachMirror(const std::function<void(SceneMirror&)>& change);
  void ConnectSignals();
  /// Shows the server's mode on the switch without sending a command.
  void SyncMode(bool editing);
  void ShowWarnings(const costume_lcm::status& status, const QString& process);
  /// Says so on a server's label when its status stopped coming (hung, or a frame slower
  /// than the status period), instead of showing figures that are no longer true.
  void ShowSilence();
  /// The status bar's warning, clipped to the room left; whole in its tooltip.
  void SetWarning(const QString& text);
  void ToggleExport();

  FrontendOptions options_;
  std::unique_ptr<CatalogSource> catalog_;
  std::unique_ptr<SceneMirror> mirror_;
  std::unique_ptr<SceneMirror> pending_mirror_;
  std::unique_ptr<CommandSender> sender_;
  std::unique_ptr<BusLink> link_;
  std::unique_ptr<BusThread> thread_;
  ClothFrameAssembler assembler_;
  std::optional<ClothFrame> last_frame_;
  std::optional<Eigen::Vector3d> last_grab_;
  std::optional<Eigen::Vector3d> last_cursor_;
  bool warned_mismatch_ = false;
  bool lists_lack_thumbnails_ = false;
  /// The thumbnails child ended since the last refresh: what is still missing will not come.
  bool thumbnails_tried_ = false;
  /// Where the import dialog opens: the folder of the last files imported.
  QString import_folder_;
  /// Each server's warnings in its last status ("sim", "haptic").
  QHash<QString, QStringList> previous_warnings_;
  /// Since the designer last switched modes.
  QElapsedTimer mode_sent_;
  /// Since each server's last status; invalid while it is not running.
  QElapsedTimer sim_status_age_;
  QElapsedTimer haptic_status_age_;

  ViewWidget* view_ = nullptr;
  ChildProcesses* children_ = nullptr;
  FrameExporter* exporter_ = nullptr;
  QListWidget* lists_[3] = {};
  QPushButton* load_buttons_[3] = {};
  MaterialPanel* material_ = nullptr;
  SolverPanel* solver_ = nullptr;
  CollisionPanel* collision_ = nullptr;
  PosturePanel* posture_ = nullptr;
  QAction* play_ = nullptr;
  QAction* pause_ = nullptr;
  QAction* stop_ = nullptr;
  QAction* export_ = nullptr;
  QAction* import_actions_[3] = {nullptr, nullptr, nullptr};
  QAction* start_server_ = nullptr;
  QRadioButton* animation_mode_ = nullptr;
  QRadioButton* editing_mode_ = nullptr;
  QDoubleSpinBox* radius_ = nullptr;
  QDoubleSpinBox* device_scale_ = nullptr;
  QPushButton* stretch_ = nullptr;
  QPushButton* undo_ = nullptr;
  QPushButton* redo_ = nullptr;
  QLineEdit* version_label_ = nullptr;
  QPushButton* save_ = nullptr;
  QActionGroup* devices_ = nullptr;
  QAction* connect_device_ = nullptr;
  QAction* disconnect_device_ = nullptr;
  QLabel* sim_label_ = nullptr;
  QLabel* haptic_label_ = nullptr;
  QLabel* device_label_ = nullptr;
  QLabel* warning_label_ = nullptr;
  QLabel* force_label_ = nullptr;
  QPlainTextEdit* log_ = nullptr;
};

}  // namespace costume::frontend
