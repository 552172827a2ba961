#include "frontend/main_window.h"

#include <QButtonGroup>
#include <QCloseEvent>
#include <QDateTime>
#include <QDir>
#include <QDockWidget>
#include <QElapsedTimer>
#include <QFileDialog>
#include <QFormLayout>
#include <QGuiApplication>
#include <QHBoxLayout>
#include <QMenu>
#include <QMenuBar>
#include <QMessageBox>
#include <QPainter>
#include <QPixmap>
#include <QRegularExpression>
#include <QScrollArea>
#include <QScrollBar>
#include <QSignalBlocker>
#include <QSizePolicy>
#include <QStatusBar>
#include <QStyle>
#include <QTabWidget>
#include <QTimer>
#include <QToolBar>
#include <QVBoxLayout>
#include <algorithm>
#include <iterator>

#include "sim_core/common/input_error.h"

namespace costume::frontend {
namespace {

using Status = costume_lcm::status;

const char* kListTitles[3] = {"Avatars", "Costumes", "Animations"};
/// Per list: what `costume-catalog import --kind` calls its entries, and the files it reads
/// (docs/catalog.md).
const char* kImportKinds[3] = {"avatar", "garment", "animation"};
const char* kImportHints[3] = {
    "Add avatars to the catalogue (MakeHuman's: its .obj, .mhskel and .mhw picked together)",
    "Add costumes to the catalogue (a MakeHuman garment: with its body's .obj, .mhskel and .mhw "
    "when they are not in MakeHuman's folders)",
    "Add animations to the catalogue (a DeepMimic clip finds its character file in "
    "../characters)"};
constexpr int kIdRole = Qt::UserRole;
constexpr int kNameRole = Qt::UserRole + 1;
/// A server whose status has not come for this long is shown as silent: each sends one a
/// second (a frame slower than that delays it).
constexpr qint64 kSilentAfterMs = 3000;

QString PlaybackName(std::int8_t playback) {
  switch (playback) {
    case Status::PLAYBACK_PLAYING: return "playing";
    case Status::PLAYBACK_PAUSED: return "paused";
    default: return "stopped";
  }
}

/// Stands for a thumbnail the catalogue lacks: "no picture yet" while one is being rendered,
/// "no picture" for the built-in assets without a database.
QPixmap NoThumbnail(const QString& text) {
  QPixmap pixmap(96, 96);
  pixmap.fill(QColor(200, 200, 210));
  QPainter painter(&pixmap);
  painter.setPen(QColor(90, 90, 100));
  painter.drawText(pixmap.rect(), Qt::AlignCenter | Qt::TextWordWrap, text);
  return pixmap;
}

QListWidget* MakeThumbnailList() {
  auto* list = new QListWidget;
  list->setViewMode(QListView::IconMode);
  list->setFlow(QListView::LeftToRight);
  list->setWrapping(false);  // one row that scrolls sideways
  list->setIconSize(QSize(96, 96));
  list->setGridSize(QSize(112, 128));
  list->setMovement(QListView::Static);
  list->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOn);
  list->setFixedHeight(160);
  return list;
}

/// The busy cursor while it lives. Building the view's copy of a scene reads the catalogue's
/// entries, fits the garments and may search the arms' spread: over a second for MakeHuman's
/// suit with a motion-capture clip, during which the window cannot draw.
class BusyCursor {
 public:
  BusyCursor() { QGuiApplication::setOverrideCursor(Qt::WaitCursor); }
  ~BusyCursor() { QGuiApplication::restoreOverrideCursor(); }
  BusyCursor(const BusyCursor&) = delete;
  BusyCursor& operator=(const BusyCursor&) = delete;
};

}  // namespace

QString FormatSimStatus(const Status& s) {
  QString text = QString("sim %1 Hz · %2 it · %3 ms (max %4) · frame %5, %6 s · %7 · %8")
                     .arg(s.measured_rate, 0, 'f', 1)
                     .arg(s.solver_iterations)
                     .arg(s.frame_time_ms, 0, 'f', 1)
                     .arg(s.max_frame_time_ms, 0, 'f', 1)
                     .arg(s.frame)
                     .arg(s.sim_time, 0, 'f', 2)
                     .arg(PlaybackName(s.playback))
                     .arg(s.mode == Status::MODE_EDITING ? "editing" : "animation");
  if (s.undo_depth > 0 || s.redo_depth > 0) {
    text += QString(" · undo %1 redo %2").arg(s.undo_depth).arg(s.redo_depth);
  }
  if (s.overruns > 0) text += QString(" · %1 overruns").arg(s.overruns);
  return text;
}

QString FormatHapticStatus(const Status& s) {
  QString text = QString("haptic %1 Hz · tick %2 ms")
                     .arg(s.measured_rate, 0, 'f', 0)
                     .arg(s.frame_time_ms, 0, 'f', 3);
  if (s.period_p99_us > 0.0) text += QString(" · p99 %1 µs").arg(s.period_p99_us, 0, 'f', 0);
  if (s.missed_ticks > 0) text += QString(" · %1 missed").arg(s.missed_ticks);
  return text;
}

MainWindow::MainWindow(bus::MessageBus& bus, FrontendOptions options,
                       std::unique_ptr<CatalogSource> catalog, QWidget* parent)
    : QMainWindow(parent), options_(std::move(options)), catalog_(std::move(catalog)) {
  mirror_ = std::make_unique<SceneMirror>(LoadScene(options_.builtin, options_.scene_file));
  sender_ = std::make_unique<CommandSender>(bus);
  link_ = std::make_unique<BusLink>(bus);
  setWindowTitle("Costume Designer — " + QString::fromStdString(mirror_->scene().name));

  view_ = new ViewWidget;
  view_->SetMirror(mirror_.get());
  setCentralWidget(view_);
  children_ = new ChildProcesses(options_.servers, this);
  exporter_ = new FrameExporter(*view_, this);

  auto* lists_dock = new QDockWidget("Catalogue", this);
  lists_dock->setWidget(BuildLists());
  lists_dock->setFeatures(QDockWidget::DockWidgetMovable | QDockWidget::DockWidgetFloatable);
  addDockWidget(Qt::BottomDockWidgetArea, lists_dock);

  auto* tabs = new QTabWidget;
  material_ = new MaterialPanel(FabricPresets());
  solver_ = new SolverPanel;
  collision_ = new CollisionPanel;
  posture_ = new PosturePanel;
  tabs->addTab(BuildEditing(), "Editing");
  tabs->addTab(material_, "Fabric");
  tabs->addTab(solver_, "Solver");
  tabs->addTab(collision_, "Collision");
  tabs->addTab(posture_, "Posture");
  auto* controls_dock = new QDockWidget("Controls", this);
  auto* scroll = new QScrollArea;
  scroll->setWidget(tabs);
  scroll->setWidgetResizable(true);
  // As wide as the widest tab needs: narrower, the dock scrolled sideways and clipped the
  // fields' right edges at 1280 × 800. It still scrolls up and down on a short screen.
  scroll->setMinimumWidth(tabs->minimumSizeHint().width() +
                          scroll->verticalScrollBar()->sizeHint().width() +
                          2 * scroll->frameWidth());
  controls_dock->setWidget(scroll);
  controls_dock->setFeatures(QDockWidget::DockWidgetMovable | QDockWidget::DockWidgetFloatable);
  addDockWidget(Qt::RightDockWidgetArea, controls_dock);

  log_ = new QPlainTextEdit;
  log_->setReadOnly(true);
  log_->setMaximumBlockCount(500);
  auto* log_dock = new QDockWidget("Messages", this);
  log_dock->setWidget(log_);
  addDockWidget(Qt::RightDockWidgetArea, log_dock);

  BuildMenus();
  BuildStatusBar();
  ConnectSignals();
  FillLists();
  // The fields start at the scene's settings, so Apply without changes is a no-op request.
  SyncSettingsPanels();
  Log("scene '" + QString::fromStdString(mirror_->scene().name) + "' mirrored: " +
      QString::number(mirror_->num_particles()) + " particles; catalogue: " +
      QString::fromStdString(catalog_->Describe()));
}

MainWindow::~MainWindow() {
  if (thread_) thread_->Stop();
}

void MainWindow::StartBusThread() {
  if (thread_) return;
  thread_ = std::make_unique<BusThread>(*link_);
  thread_->start();
}

void MainWindow::StartChildren() {
  QString error;
  if (options_.start_sim_server && !children_->StartSimServer(&error)) Warn("error: " + error);
  if (!options_.device.isEmpty()) {
    if (QAction* action = device_action(options_.device)) action->setChecked(true);
    ConnectDevice(options_.device);
  }
  MakeMissingThumbnails();  // a catalogue made with --no-thumbnails, or saved versions
}

void MainWindow::RestartSimServer() {
  if (children_->sim_running()) {
    Log("the simulation server is running");
    return;
  }
  QString error;
  if (!children_->StartSimServer(&error)) {
    Warn("error: " + error);
    return;
  }
  // A fresh server runs the start scene from frame 0: the view follows it when its frames
  // come, as after a load.
  try {
    const BusyCursor busy;
    pending_mirror_ =
        std::make_unique<SceneMirror>(LoadScene(options_.builtin, options_.scene_file));
  } catch (const sim::InputError& refusal) {
    Log(QString("the view keeps its scene: ") + refusal.what());
  }
  SetWarning("");
  Log("simulation server started");
}

void MainWindow::RefreshCatalogue() {
  thumbnails_tried_ = false;
  FillLists();
  MakeMissingThumbnails();
}

void MainWindow::ImportFiles(EntryKind kind, const QStringList& files) {
  if (files.isEmpty()) return;
  import_folder_ = QFileInfo(files.front()).absolutePath();
  const QStringList arguments = ImportArguments(kImportKinds[static_cast<int>(kind)], files);
  QString error;
  if (children_->Import(arguments, &error)) {
    Log("catalogue: costume-catalog import " + arguments.join(' '));
  } else {
    Warn("catalogue: nothing imported: " + error);
  }
}

void MainWindow::ShowImportResult(int code, const QString& output) {
  if (code == 0) {
    Log("catalogue: imported");
    RefreshCatalogue();
    PickImported(output);
    return;
  }
  // The program's refusal ("error: 1 problem; nothing was imported:" and a line per bad file
  // naming what is wrong with it) follows its progress lines.
  const qsizetype at =
      output.indexOf(QRegularExpression("^error: ", QRegularExpression::MultilineOption));
  if (at >= 0) {
    QString reason = output.mid(at + 7).simplified();
    // The program names its own options; here the body is picked in the dialog instead.
    if (reason.contains("--makehuman-body")) {
      reason += " — here: pick the garment together with its body's .obj, .mhskel and .mhw "
                "(the filter \"MakeHuman garments with their body\")";
    }
    Warn("catalogue: " + reason);
    return;
  }
  // Refused before reading any file (options it could not take): its last line says why.
  const QStringList lines = output.trimmed().split('\n');
  Warn(QString("catalogue: nothing was imported (costume-catalog import exited with code %1): %2")
           .arg(code)
           .arg(lines.isEmpty() ? QString() : lines.back()));
}

void MainWindow::PickImported(const QString& output) {
  // The program's last lines: "stored garment 'scarf' as id 11", one per entry.
  const QRegularExpression stored("^stored (avatar|animation|garment) '(.*)' as id \\d+$",
                                  QRegularExpression::MultilineOption);
  QRegularExpressionMatch last;
  for (const QRegularExpressionMatch& match : stored.globalMatch(output)) last = match;
  if (!last.hasMatch()) return;
  const int k = static_cast<int>(std::find(std::begin(kImportKinds), std::end(kImportKinds),
                                           last.captured(1).toStdString()) -
                                 std::begin(kImportKinds));
  const QList<QListWidgetItem*> found = lists_[k]->findItems(last.captured(2), Qt::MatchExactly);
  if (found.isEmpty()) return;
  lists_[k]->setCurrentItem(found.front());
  lists_[k]->scrollToItem(found.front());
}

void MainWindow::MakeMissingThumbnails() {
  if (!catalog_->IsDatabase() || !lists_lack_thumbnails_) return;
  QString error;
  if (children_->MakeMissingThumbnails(&error)) {
    Log("catalogue: rendering the missing thumbnails");
  } else {
    Warn("catalogue: no thumbnails made: " + error);
  }
}

QWidget* MainWindow::BuildLists() {
  auto* box = new QWidget;
  auto* layout = new QHBoxLayout(box);
  for (int k = 0; k < 3; ++k) {
    auto* column = new QVBoxLayout;
    column->addWidget(new QLabel(kListTitles[k]));
    lists_[k] = MakeThumbnailList();
    lists_[k]->setContextMenuPolicy(Qt::CustomContextMenu);
    connect(lists_[k], &QWidget::customContextMenuRequested, this,
            [this, k](const QPoint& at) { OfferRemoval(static_cast<EntryKind>(k), at); });
    column->addWidget(lists_[k]);
    load_buttons_[k] = new QPushButton(QString("Load ") + kListTitles[k]);
    column->addWidget(load_buttons_[k]);
    layout->addLayout(column);
  }
  return box;
}

void MainWindow::OfferRemoval(EntryKind kind, const QPoint& at) {
  const QListWidgetItem* item = list(kind)->itemAt(at);
  if (!item || !catalog_->IsDatabase()) return;
  const QString name = item->data(kNameRole).toString();
  QMenu menu;
  QAction* remove = menu.addAction(QString("Remove '%1' from the catalogue…").arg(name));
  if (menu.exec(list(kind)->viewport()->mapToGlobal(at)) != remove) return;
  const auto answer = QMessageBox::question(
      this, "Remove from the catalogue",
      QString("Remove '%1' and all its versions from %2? This cannot be undone; a simulation "
              "that has it loaded keeps it.")
          .arg(name, QString::fromStdString(catalog_->Describe())));
  if (answer == QMessageBox::Yes) RemoveEntry(kind, name);
}

bool MainWindow::RemoveEntry(EntryKind kind, const QString& name) {
  const QList<QListWidgetItem*> found = list(kind)->findItems(name, Qt::MatchExactly);
  if (found.isEmpty()) return false;
  const CatalogItem item{found.front()->data(kIdRole).toLongLong(), name.toStdString(), "", {}};
  try {
    catalog_->Remove(item);
  } catch (const sim::InputError& error) {
    Warn(QString("catalogue: '%1' not removed: %2").arg(name, error.what()));
    return false;
  }
  Log(QString("catalogue: removed '%1'").arg(name));
  FillLists();
  return true;
}

void MainWindow::FillLists() {
  lists_lack_thumbnails_ = false;
  for (int k = 0; k < 3; ++k) {
    // Filled again after a save or a refresh: the designer's pick stays picked.
    const QListWidgetItem* picked = lists_[k]->currentItem();
    const QString picked_name = picked ? picked->data(kNameRole).toString() : QString();
    lists_[k]->clear();
    std::vector<CatalogItem> items;
    try {
      items = catalog_->List(static_cast<EntryKind>(k));
    } catch (const sim::InputError& error) {
      Log(QString("catalogue: ") + error.what());
    }
    for (const CatalogItem& item : items) {
      QPixmap thumbnail;
      if (!item.thumbnail_png.empty()) {
        thumbnail.loadFromData(item.thumbnail_png.data(),
                               static_cast<uint>(item.thumbnail_png.size()), "PNG");
      }
      if (thumbnail.isNull()) {
        lists_lack_thumbnails_ = true;
        // MakeMissingThumbnails renders it, unless its last run could not.
        const bool coming = catalog_->IsDatabase() && !thumbnails_tried_;
        thumbnail = NoThumbnail(coming ? "no picture\nyet" : "no picture");
      }
      auto* entry = new QListWidgetItem(QIcon(thumbnail), QString::fromStdString(item.name));
      entry->setData(kIdRole, QVariant::fromValue<qlonglong>(item.id));
      entry->setData(kNameRole, QString::fromStdString(item.name));
      if (!item.category.empty()) entry->setToolTip(QString::fromStdString(item.category));
      lists_[k]->addItem(entry);
      if (!picked_name.isEmpty() && entry->data(kNameRole).toString() == picked_name) {
        lists_[k]->setCurrentItem(entry);
      }
    }
  }
}

void MainWindow::LoadSelected(EntryKind kind) {
  const QListWidgetItem* item = list(kind)->currentItem();
  if (!item) return;
  const qlonglong id = item->data(kIdRole).toLongLong();
  const QString name = item->data(kNameRole).toString();
  sender_->Load(kind, id, name.toStdString());
  Log(QString("load %1 '%2' sent").arg(kListTitles[static_cast<int>(kind)]).arg(name));
  MirrorLoad(kind, CatalogItem{id, name.toStdString(), "", {}});
}

void MainWindow::MirrorLoad(EntryKind kind, const CatalogItem& item) {
  try {
    const BusyCursor busy;
    QElapsedTimer timer;
    timer.start();
    // Built on the pending scene when loads follow each other before the server answers.
    sim::SceneDescription scene = (pending_mirror_ ? *pending_mirror_ : *mirror_).scene();
    catalog_->ApplyToScene(kind, item, scene);
    pending_mirror_ = std::make_unique<SceneMirror>(std::move(scene));
    Log(QString("the view follows once the server runs the new scene (%1 particles; its copy "
                "built in %2 s)")
            .arg(pending_mirror_->num_particles())
            .arg(static_cast<double>(timer.elapsed()) / 1000.0, 0, 'f', 1));
  } catch (const sim::InputError& error) {
    Log(QString("the view keeps its scene: ") + error.what());
  }
}

bool MainWindow::AdoptPendingMirror(const ClothFrame& frame) {
  if (!pending_mirror_) return false;
  const int count = static_cast<int>(frame.positions.size());
  // The server rebuilds its simulation for a load: its frame numbers start again.
  const bool rebuilt = last_frame_ && frame.frame < last_frame_->frame;
  if (count != pending_mirror_->num_particles() ||
      (!rebuilt && count == mirror_->num_particles())) {
    return false;
  }
  mirror_ = std::move(pending_mirror_);
  view_->SetMirror(mirror_.get());
  warned_mismatch_ = false;
  SyncSettingsPanels();
  Log(QString("the view follows the loaded scene: %1 particles").arg(count));
  return true;
}

void MainWindow::SyncSettingsPanels() {
  solver_->SetSettings(mirror_->scene().solver);
  collision_->SetSettings(sim::CollisionSettingsOf(mirror_->scene()));
  if (mirror_->scene().avatar) {
    const sim::AvatarSpec& avatar = *mirror_->scene().avatar;
    posture_->SetPosture(avatar.motion.posture, avatar.avatar->skeleton());
    posture_->SetArmSpread(avatar.auto_arm_spread,
                           avatar.auto_arm_spread ? mirror_->arm_spread().angle
                                                  : avatar.motion.arm_spread);
  }
}

void MainWindow::ForEachMirror(const std::function<void(SceneMirror&)>& change) {
  change(*mirror_);
  if (pending_mirror_) change(*pending_mirror_);
}

QWidget* MainWindow::BuildEditing() {
  auto* box = new QWidget;
  auto* form = new QFormLayout(box);
  animation_mode_ = new QRadioButton("Animation (mode A)");
  editing_mode_ = new QRadioButton("Editing (mode B)");
  animation_mode_->setChecked(!options_.servers.editing);
  editing_mode_->setChecked(options_.servers.editing);
  auto* modes = new QButtonGroup(box);
  modes->addButton(animation_mode_);
  modes->addButton(editing_mode_);
  auto* mode_row = new QHBoxLayout;
  mode_row->addWidget(animation_mode_);
  mode_row->addWidget(editing_mode_);
  form->addRow("Mode", mode_row);
  radius_ = new QDoubleSpinBox;
  radius_->setRange(0.005, 0.5);
  radius_->setDecimals(3);
  radius_->setSingleStep(0.01);
  radius_->setSuffix(" m");
  radius_->setValue(options_.servers.radius);
  radius_->setKeyboardTracking(false);
  radius_->setToolTip("Selection sphere radius [0.005 … 0.5 m]; a running haptic server "
                      "takes it from its next grab");
  form->addRow("Selection radius", radius_);
  device_scale_ = new QDoubleSpinBox;
  device_scale_->setRange(0.1, 20.0);
  device_scale_->setDecimals(1);
  device_scale_->setSingleStep(0.5);
  device_scale_->setValue(options_.servers.workspace_scale);
  device_scale_->setToolTip(
      "OpenHaptics and CyberGrasp: scene metres per device metre [0.1 … 20]. The device's "
      "workspace is centred on the cloth when it connects and covers this many times its own "
      "size (a Touch's ±8 cm reach ±24 cm at 3). Forces are not scaled, so a cloth stiffness "
      "is felt this many times stiffer (the force safety limits it). Taken at the next Connect.");
  form->addRow("Device scale", device_scale_);
  stretch_ = new QPushButton("Eliminate stretch energy");
  form->addRow(stretch_);
  undo_ = new QPushButton("Undo edit");
  redo_ = new QPushButton("Redo edit");
  auto* undo_row = new QHBoxLayout;
  undo_row->addWidget(undo_);
  undo_row->addWidget(redo_);
  form->addRow(undo_row);
  version_label_ = new QLineEdit;
  version_label_->setPlaceholderText("label of the new version");
  save_ = new QPushButton("Save as new version");
  form->addRow("Version label", version_label_);
  form->addRow(save_);
  view_->SetSelectionRadius(radius_->value());
  view_->SetSelectionVisible(editing_mode_->isChecked());
  return box;
}

void MainWindow::BuildMenus() {
  QMenu* file = menuBar()->addMenu("&File");
  export_ = file->addAction("Export animation (PNG frames)");
  export_->setCheckable(true);
  QAction* shot = file->addAction("Save screenshot");
  QAction* refresh = file->addAction("Refresh catalogue");
  refresh->setShortcut(QKeySequence::Refresh);
  refresh->setToolTip("List the catalogue's entries again (another program may have imported "
                      "some) and render the thumbnails they lack");
  connect(refresh, &QAction::triggered, this, [this] { RefreshCatalogue(); });
  for (int k = 0; k < 3; ++k) {
    const auto kind = static_cast<EntryKind>(k);
    import_actions_[k] =
        file->addAction(QString("Import %1…").arg(QString(kListTitles[k]).toLower()));
    import_actions_[k]->setEnabled(catalog_->IsDatabase());
    import_actions_[k]->setToolTip(catalog_->IsDatabase()
                                       ? kImportHints[k]
                                       : "This build has no catalogue database to import into");
    connect(import_actions_[k], &QAction::triggered, this, [this, kind, k] {
      const QStringList files = QFileDialog::getOpenFileNames(
          this, QString("Import %1").arg(QString(kListTitles[k]).toLower()), import_folder_,
          QString::fromStdString(ImportFilter(kind)));
      if (!files.isEmpty()) ImportFiles(kind, files);
    });
  }
  file->addSeparator();
  QAction* quit = file->addAction("Quit");
  connect(export_, &QAction::triggered, this, [this] { ToggleExport(); });
  connect(shot, &QAction::triggered, this, [this] {
    const QString path = QString("out/screenshot_%1.png")
                             .arg(QDateTime::currentDateTime().toString("yyyyMMdd_hhmmss"));
    QDir().mkpath("out");
    Log(FrameExporter::Screenshot(*view_, path) ? "screenshot " + path
                                                : "error: cannot write " + path);
  });
  connect(quit, &QAction::triggered, this, &QWidget::close);

  QMenu* edit = menuBar()->addMenu("&Edit");
  connect(edit->addAction("Undo edit"), &QAction::triggered, undo_, &QPushButton::click);
  connect(edit->addAction("Redo edit"), &QAction::triggered, redo_, &QPushButton::click);

  QToolBar* playback = addToolBar("Playback");
  playback->setToolButtonStyle(Qt::ToolButtonTextBesideIcon);
  play_ = playback->addAction(style()->standardIcon(QStyle::SP_MediaPlay), "Play");
  pause_ = playback->addAction(style()->standardIcon(QStyle::SP_MediaPause), "Pause");
  stop_ = playback->addAction(style()->standardIcon(QStyle::SP_MediaStop), "Stop");
  QMenu* sim = menuBar()->addMenu("&Simulation");
  sim->addAction(play_);
  sim->addAction(pause_);
  sim->addAction(stop_);
  sim->addSeparator();
  start_server_ = sim->addAction("Start server");
  start_server_->setToolTip("Start the simulation server again after it stopped (with the "
                            "scene the window was started with)");
  connect(start_server_, &QAction::triggered, this, [this] { RestartSimServer(); });

  QMenu* device = menuBar()->addMenu("&Device");
  devices_ = new QActionGroup(this);
  const QStringList labels = {"Simulated", "Mouse", "OpenHaptics (Phantom/Touch)", "CyberGrasp"};
  for (int i = 0; i < DeviceNames().size(); ++i) {
    QAction* action = device->addAction(labels[i]);
    action->setCheckable(true);
    action->setData(DeviceNames()[i]);
    devices_->addAction(action);
  }
  devices_->actions()[1]->setChecked(true);  // the mouse: always there
  device->addSeparator();
  connect_device_ = device->addAction("Connect");
  disconnect_device_ = device->addAction("Disconnect");
}

QAction* MainWindow::device_action(const QString& device) const {
  for (QAction* action : devices_->actions()) {
    if (action->data().toString() == device) return action;
  }
  return nullptr;
}

void MainWindow::BuildStatusBar() {
  sim_label_ = new QLabel("sim: no status yet");
  haptic_label_ = new QLabel("haptic: no status yet");
  device_label_ = new QLabel("device: disconnected");
  force_label_ = new QLabel("force —");
  force_label_->setToolTip("Force on the device after clamping and ramping [N] (requested force "
                           "before them in brackets)");
  warning_label_ = new QLabel;
  warning_label_->setStyleSheet("color: #a05000");
  // The figures keep their width and the warning takes what is left, clipped (the whole of
  // it in the tooltip and the Messages panel): a long warning squeezed the haptic figures
  // to "440 mis" at 1280 pixels wide.
  warning_label_->setSizePolicy(QSizePolicy::Ignored, QSizePolicy::Preferred);
  statusBar()->addWidget(sim_label_);
  statusBar()->addWidget(haptic_label_);
  statusBar()->addWidget(device_label_);
  statusBar()->addWidget(force_label_);
  statusBar()->addWidget(warning_label_, 1);
}

void MainWindow::ConnectSignals() {
  // Unacknowledged commands are resent (command_sender.h); given-up ones go to the log.
  auto* resend = new QTimer(this);
  connect(resend, &QTimer::timeout, this, [this] {
    for (const std::string& line : sender_->ResendDue()) Log(QString::fromStdString(line));
  });
  resend->start(static_cast<int>(bus::ResendPolicy{}.period_us / 1000));
  auto* silence = new QTimer(this);
  connect(silence, &QTimer::timeout, this, &MainWindow::ShowSilence);
  silence->start(1000);
  connect(link_.get(), &BusLink::clothChunk, this, &MainWindow::OnClothChunk);
  connect(link_.get(), &BusLink::simStatus, this, &MainWindow::OnSimStatus);
  connect(link_.get(), &BusLink::hapticStatus, this, &MainWindow::OnHapticStatus);
  connect(link_.get(), &BusLink::deviceState, this, &MainWindow::OnDeviceState);
  connect(link_.get(), &BusLink::feedback, this, &MainWindow::OnFeedback);

  for (int k = 0; k < 3; ++k) {
    const auto kind = static_cast<EntryKind>(k);
    connect(lists_[k], &QListWidget::itemDoubleClicked, this, [this, kind] { LoadSelected(kind); });
    connect(load_buttons_[k], &QPushButton::clicked, this, [this, kind] { LoadSelected(kind); });
  }
  connect(material_, &MaterialPanel::materialRequested, this, [this](const sim::Material& m) {
    sender_->SetMaterial(-1, m);
  });
  connect(solver_, &SolverPanel::solverRequested, this, [this](const sim::SolverSettings& s) {
    sender_->SetSolver(s);
    ForEachMirror([&s](SceneMirror& mirror) { mirror.SetSolver(s); });
    Log("solver sent: the server changes it in place, the cloth keeping its state");
  });
  connect(collision_, &CollisionPanel::collisionRequested, this,
          [this](const sim::CollisionSettings& s) {
            sender_->SetCollision(s);
            ForEachMirror([&s](SceneMirror& mirror) { mirror.SetCollision(s); });
            Log("collision sent: the server changes it in place (only a new method builds a "
                "new collider: superquadrics take about half a second, once per avatar)");
          });
  connect(posture_, &PosturePanel::postureRequested, this,
          [this](const std::vector<JointAngles>& joints, double heading,
                 const sim::ArmSpreadRequest& spread) {
            sender_->SetPosture(joints, heading, spread);
            ForEachMirror(
                [&](SceneMirror& mirror) { mirror.SetPosture(joints, heading, spread); });
            // The greyed angles show what "auto" chose.
            if (spread.kind == sim::ArmSpreadRequest::Kind::kAuto) {
              posture_->SetArmSpread(true, mirror_->arm_spread().angle);
            }
            Log("posture sent; " + QString::fromStdString(
                                       sim::DescribeArmSpread(mirror_->arm_spread())));
            view_->update();
          });
  connect(play_, &QAction::triggered, this, [this] { sender_->Play(); });
  connect(pause_, &QAction::triggered, this, [this] { sender_->Pause(); });
  connect(stop_, &QAction::triggered, this, [this] { sender_->Stop(); });
  connect(animation_mode_, &QRadioButton::toggled, this, [this](bool on) {
    if (!on) return;
    sender_->SetMode(false);
    mode_sent_.start();
    view_->SetSelectionVisible(false);
  });
  connect(editing_mode_, &QRadioButton::toggled, this, [this](bool on) {
    if (!on) return;
    sender_->SetMode(true);
    mode_sent_.start();
    view_->SetSelectionVisible(true);
  });
  connect(radius_, &QDoubleSpinBox::valueChanged, this, [this](double r) {
    view_->SetSelectionRadius(r);
    children_->options().radius = r;   // a device connected later starts with it
    sender_->SetSelectionRadius(r);    // a running haptic server takes it from its next grab
  });
  connect(stretch_, &QPushButton::clicked, this,
          [this] { sender_->EliminateStretch(StretchCentre(), radius_->value()); });
  connect(undo_, &QPushButton::clicked, this, [this] { sender_->Undo(); });
  connect(redo_, &QPushButton::clicked, this, [this] { sender_->Redo(); });
  connect(save_, &QPushButton::clicked, this, [this] {
    QString label = version_label_->text().trimmed();
    if (label.isEmpty()) {
      label = "edit " + QDateTime::currentDateTime().toString("yyyy-MM-dd hh:mm");
    }
    sender_->SaveVersion(label.toStdString());
    Log("save version '" + label + "' sent");
  });
  connect(view_, &ViewWidget::pointerSample, this,
          [this](const Eigen::Vector3d& p, int buttons, bool inside) {
            sender_->Pointer(p, buttons, inside);
          });
  connect(view_, &ViewWidget::grabStarted, this, [this](const Eigen::Vector3d& p) {
    last_grab_ = p;
    if (!editing_mode_->isChecked()) Log("grabs act in editing mode (mode B) only");
  });
  connect(view_, &ViewWidget::grabEnded, this, [this](const Eigen::Vector3d& p) { last_grab_ = p; });
  connect(connect_device_, &QAction::triggered, this,
          [this] { ConnectDevice(devices_->checkedAction()->data().toString()); });
  connect(disconnect_device_, &QAction::triggered, this, [this] { children_->DisconnectDevice(); });
  connect(children_, &ChildProcesses::deviceChanged, this,
          [this](const QString& device, bool connected) {
            device_label_->setText("device: " + device + (connected ? " connected" : " disconnected"));
            if (!connected) {
              view_->HideCursor();
              haptic_status_age_.invalidate();
              haptic_label_->setText("haptic: not running");
            }
          });
  connect(children_, &ChildProcesses::deviceError, this,
          [this](const QString& device, const QString& message) {
            device_label_->setText("device: " + device + " failed");
            SetWarning(message.section('\n', -1));
            Log("device " + device + ": " + message);
          });
  connect(children_, &ChildProcesses::output, this,
          [this](const QString& process, const QString& line) { Log(process + ": " + line); });
  connect(children_, &ChildProcesses::importFinished, this, &MainWindow::ShowImportResult);
  connect(children_, &ChildProcesses::simServerExited, this, [this](const QString& how) {
    sim_status_age_.invalidate();  // not silent: gone
    sim_label_->setText("sim: not running");
    Warn("the simulation server stopped (" + how + "; its last lines are above): Simulation > "
         "Start server runs it again");
  });
  connect(exporter_, &FrameExporter::videoDone, this, &MainWindow::Log);
  connect(children_, &ChildProcesses::thumbnailsMade, this, [this](int code) {
    thumbnails_tried_ = true;
    FillLists();  // not MakeMissingThumbnails: one that cannot be made would loop
    Log(code == 0 ? QString("catalogue: thumbnails made")
                  : QString("catalogue: making thumbnails failed (code %1)").arg(code));
  });
}

void MainWindow::ToggleExport() {
  if (exporter_->recording()) {
    Log(exporter_->Finish());
    export_->setChecked(false);
    return;
  }
  const QString folder = QString("out/export_%1")
                             .arg(QDateTime::currentDateTime().toString("yyyyMMdd_hhmmss"));
  QString error;
  if (!exporter_->Start(folder, &error)) {
    Warn("error: " + error);
    export_->setChecked(false);
    return;
  }
  export_->setChecked(true);
  Log("exporting frames to " + folder + " (choose the menu item again to stop)");
}

void MainWindow::ConnectDevice(const QString& device) {
  ServerOptions& servers = children_->options();
  servers.workspace_scale = device_scale_->value();
  servers.workspace_centre = ClothCentroid();
  if (IsPhysicalDevice(device)) {
    const Eigen::Vector3d& c = *servers.workspace_centre;
    Log(QString("%1: workspace centred on the cloth at (%2, %3, %4) m, scale %5")
            .arg(device)
            .arg(c.x(), 0, 'f', 3)
            .arg(c.y(), 0, 'f', 3)
            .arg(c.z(), 0, 'f', 3)
            .arg(servers.workspace_scale));
  }
  QString error;
  if (!children_->ConnectDevice(device, &error)) Warn("error: " + error);
}

Eigen::Vector3d MainWindow::StretchCentre() const {
  if (last_grab_) return *last_grab_;
  if (last_cursor_) return *last_cursor_;
  return ClothCentroid();
}

Eigen::Vector3d MainWindow::ClothCentroid() const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const auto& cloth = view_->cloth_positions();
  for (const Eigen::Vector3f& p : cloth) sum += p.cast<double>();
  return cloth.empty() ? sum : Eigen::Vector3d(sum / static_cast<double>(cloth.size()));
}

void MainWindow::OnClothChunk(const costume_lcm::cloth_frame& chunk) {
  sender_->Acknowledge(chunk.command_seq);  // every chunk: a lost one must not hold resends
  std::optional<ClothFrame> frame = assembler_.Add(chunk);
  if (!frame) return;
  AdoptPendingMirror(*frame);
  if (static_cast<int>(frame->positions.size()) != mirror_->num_particles()) {
    if (!warned_mismatch_) {
      warned_mismatch_ = true;
      Log(QString("the server runs %1 particles, the view mirrors %2 ('%3'): the cloth is not "
                  "drawn until the scenes match")
              .arg(frame->positions.size())
              .arg(mirror_->num_particles())
              .arg(QString::fromStdString(mirror_->scene().name)));
    }
    return;
  }
  mirror_->Follow(*frame);
  view_->SetFrame(*frame);
  last_frame_ = std::move(frame);
}

bool IsPeriodicFigure(const std::string& warning) {
  return warning.rfind("loop:", 0) == 0 || warning.rfind("safety:", 0) == 0;
}

void MainWindow::SetWarning(const QString& text) {
  warning_label_->setText(text);
  warning_label_->setToolTip(text);
}

void MainWindow::ShowWarnings(const Status& status, const QString& process) {
  QStringList figures;
  QStringList& previous = previous_warnings_[process];
  QStringList current;
  for (const std::string& warning : status.warnings) {
    const QString text = QString::fromStdString(warning);
    if (IsPeriodicFigure(warning)) {
      figures << text;  // the haptic server's once-a-second figures: a tooltip, not a warning
      continue;
    }
    current << text;
    // A standing warning (a refused real-time priority) rides on every status, for windows
    // that start later: shown once, it would otherwise bury the log and the status bar.
    if (!previous.contains(text)) {
      SetWarning(process + ": " + text);
      Log(process + " warning: " + text);
    }
    if (warning.rfind("command SAVE_VERSION: saved ", 0) == 0) {
      RefreshCatalogue();  // the new version is listed, and its picture made
    }
    if (pending_mirror_ && warning.rfind("command LOAD_", 0) == 0) {
      pending_mirror_.reset();  // the server refused the load: its scene stays
      Log("the view keeps its scene");
    }
  }
  previous = current;
  // The whole status line (a narrow window clips it), then the once-a-second figures.
  QLabel* label = process == "haptic" ? haptic_label_ : sim_label_;
  label->setToolTip(figures.isEmpty() ? label->text()
                                      : label->text() + "\n" + figures.join("\n"));
}

void MainWindow::ShowSilence() {
  const auto mark = [](QLabel* label, const QElapsedTimer& since, const QString& name) {
    if (!since.isValid() || since.elapsed() < kSilentAfterMs) return;
    label->setText(QString("%1: no status for %2 s (busy or hung)")
                       .arg(name)
                       .arg(since.elapsed() / 1000));
  };
  mark(sim_label_, sim_status_age_, "sim");
  mark(haptic_label_, haptic_status_age_, "haptic");
}

void MainWindow::OnSimStatus(const Status& status) {
  sim_status_age_.start();
  sim_label_->setText(FormatSimStatus(status));
  ShowWarnings(status, "sim");
  SyncMode(status.mode == Status::MODE_EDITING);
  undo_->setToolTip(QString("%1 edit(s) the server can undo").arg(status.undo_depth));
  redo_->setToolTip(QString("%1 undone edit(s) the server can redo").arg(status.redo_depth));
}

void MainWindow::SyncMode(bool editing) {
  // The server's mode wins, except just after the designer switched (the status on its way
  // may predate the switch).
  if (mode_sent_.isValid() && mode_sent_.elapsed() < 2000) return;
  if (editing_mode_->isChecked() == editing) return;
  const QSignalBlocker block_a(animation_mode_);
  const QSignalBlocker block_b(editing_mode_);
  (editing ? editing_mode_ : animation_mode_)->setChecked(true);
  view_->SetSelectionVisible(editing);
}

void MainWindow::OnHapticStatus(const Status& status) {
  haptic_status_age_.start();
  haptic_label_->setText(FormatHapticStatus(status));
  ShowWarnings(status, "haptic");
}

void MainWindow::OnDeviceState(const costume_lcm::device_state& state) {
  const Eigen::Vector3d position(state.position[0], state.position[1], state.position[2]);
  const Eigen::Quaterniond q(state.orientation[0], state.orientation[1], state.orientation[2],
                             state.orientation[3]);
  if (!position.allFinite() || !q.coeffs().allFinite() || q.norm() < 0.5) return;
  last_cursor_ = position;
  view_->SetCursor(position, q.normalized(),
                   state.model == costume_lcm::device_state::MODEL_CYBERGRASP);
}

void MainWindow::OnFeedback(const costume_lcm::feedback& message) {
  const Eigen::Vector3d force(message.force[0], message.force[1], message.force[2]);
  const Eigen::Vector3d requested(message.requested_force[0], message.requested_force[1],
                                  message.requested_force[2]);
  force_label_->setText(QString("force %1 N (%2)%3")
                            .arg(force.norm(), 0, 'f', 2)
                            .arg(requested.norm(), 0, 'f', 2)
                            .arg(message.clamped ? " clamped" : ""));
}

void MainWindow::Log(const QString& line) { log_->appendPlainText(line); }

void MainWindow::Warn(const QString& line) {
  SetWarning(line);
  Log(line);
}

void MainWindow::closeEvent(QCloseEvent* event) {
  if (exporter_->recording()) Log(exporter_->Finish());
  children_->StopAll();
  QMainWindow::closeEvent(event);
}

}  // namespace costume::frontend
