// The main window's controls and their commands, on the in-memory bus (memq://) and Qt's
// offscreen platform: every control publishes the right command with the right fields,
// out-of-range values are refused, status messages reach the status bar, cloth chunks reach
// the view, and a mouse press on the cloth becomes a pointer sample.
#include "frontend/main_window.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <QGuiApplication>
#include <QRegularExpression>
#include <QTest>
#include <filesystem>
#include <fstream>

#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#ifdef COSTUME_HAVE_CATALOG
#include "catalog/catalog.h"
#endif
#include "render/camera.h"
#include "tests/support/humanoid.h"
#include "tests/support/qt_app.h"
#include "tests/support/shared_data.h"

namespace costume::frontend {
namespace {

using costume::testing::WaitFor;

using Command = costume_lcm::command;

/// Publishes a simulation server status carrying `warnings` and dispatches what `bus` holds.
void PublishSimWarnings(bus::MessageBus& bus, std::vector<std::string> warnings) {
  costume_lcm::status status{};
  status.utime = bus::NowUtime();
  status.num_warnings = static_cast<std::int16_t>(warnings.size());
  status.warnings = std::move(warnings);
  ASSERT_TRUE(bus::Publish(bus, bus::kSimStatusChannel, status));
  while (bus.HandleSubscriptions(0) > 0) {
  }
}

class MainWindowTest : public ::testing::Test {
 protected:
  void SetUp() override {
    costume::testing::TestApp();
    bus::Subscribe<Command>(bus_, bus::kCommandChannel,
                            [this](const Command& c) { commands_.push_back(c); });
    bus::Subscribe<costume_lcm::pointer_sample>(
        bus_, bus::kPointerChannel,
        [this](const costume_lcm::pointer_sample& p) { pointer_.push_back(p); });
    FrontendOptions options;
    options.builtin = "hang";  // a 33 × 33 sheet: no avatar, quick to mirror
    window_ = std::make_unique<MainWindow>(bus_, options, MakeBuiltInCatalog());
    window_->resize(1200, 800);
  }

  /// Dispatches what the window published; returns the commands received since last time.
  std::vector<Command> Sent() {
    while (bus_.HandleSubscriptions(0) > 0) {
    }
    std::vector<Command> out;
    out.swap(commands_);
    return out;
  }

  /// The one command the last action sent.
  Command One() {
    const std::vector<Command> sent = Sent();
    EXPECT_EQ(sent.size(), 1u);
    return sent.empty() ? Command{} : sent.back();
  }

  bus::LcmBus bus_{"memq://"};
  std::vector<Command> commands_;
  std::vector<costume_lcm::pointer_sample> pointer_;
  std::unique_ptr<MainWindow> window_;
};

TEST_F(MainWindowTest, LoadButtonsAndDoubleClickSendLoadCommands) {
  QListWidget* avatars = window_->list(EntryKind::kAvatar);
  ASSERT_GE(avatars->count(), 1);
  avatars->setCurrentRow(0);
  window_->load_button(EntryKind::kAvatar)->click();
  Command c = One();
  EXPECT_EQ(c.kind, Command::KIND_LOAD_AVATAR);
  EXPECT_EQ(c.name, "humanoid");
  EXPECT_EQ(c.database_id, 0);

  QListWidget* clips = window_->list(EntryKind::kAnimation);
  const QList<QListWidgetItem*> walk = clips->findItems("walk", Qt::MatchExactly);
  ASSERT_EQ(walk.size(), 1);
  clips->setCurrentItem(walk[0]);
  // The list's own double-click signal (a hidden widget gets no real double click here).
  emit clips->itemDoubleClicked(walk[0]);
  const std::vector<Command> sent = Sent();
  ASSERT_FALSE(sent.empty());
  EXPECT_EQ(sent.back().kind, Command::KIND_LOAD_ANIMATION);
  EXPECT_EQ(sent.back().name, "walk");

  window_->list(EntryKind::kCostume)->setCurrentRow(2);
  window_->load_button(EntryKind::kCostume)->click();
  c = One();
  EXPECT_EQ(c.kind, Command::KIND_LOAD_COSTUME);
  EXPECT_EQ(c.name, "skirt");  // built-ins listed by name: cape, dress, skirt
}

TEST_F(MainWindowTest, FabricFieldsAndPresetsSendSetMaterial) {
  MaterialPanel* panel = window_->material_panel();
  panel->density->setValue(0.25);
  panel->stretch->setValue(2500.0);
  panel->shear->setValue(700.0);
  panel->bending->setValue(2e-5);
  panel->damping->setValue(0.002);
  panel->friction->setValue(0.6);
  panel->apply->click();
  const Command c = One();
  EXPECT_EQ(c.kind, Command::KIND_SET_MATERIAL);
  EXPECT_EQ(c.garment, -1);
  EXPECT_DOUBLE_EQ(c.material.density, 0.25);
  EXPECT_DOUBLE_EQ(c.material.stretch_stiffness, 2500.0);
  EXPECT_DOUBLE_EQ(c.material.shear_stiffness, 700.0);
  EXPECT_DOUBLE_EQ(c.material.bending_rigidity, 2e-5);
  EXPECT_DOUBLE_EQ(c.material.damping, 0.002);
  EXPECT_DOUBLE_EQ(c.material.friction, 0.6);

  const int index = panel->preset->findText("stiff_cotton");
  ASSERT_GE(index, 1);
  panel->preset->setCurrentIndex(index);
  panel->apply->click();
  const Command preset = One();
  const sim::Material cotton = sim::NamedMaterial("stiff_cotton");
  EXPECT_EQ(preset.material.name, "stiff_cotton");
  EXPECT_DOUBLE_EQ(preset.material.density, cotton.density);
  EXPECT_DOUBLE_EQ(preset.material.stretch_stiffness, cotton.stretch_stiffness);
}

TEST_F(MainWindowTest, OutOfRangeFabricValuesAreRefused) {
  MaterialPanel* panel = window_->material_panel();
  sim::Material heavy;
  heavy.density = 5.0;  // above the 2 kg/m² of the heaviest leather we allow
  QString reason;
  EXPECT_FALSE(panel->SetMaterial(heavy, &reason));
  EXPECT_TRUE(reason.contains("density = 5")) << reason.toStdString();
  EXPECT_DOUBLE_EQ(panel->density->value(), sim::Material{}.density);  // unchanged
  sim::Material nan_friction;
  nan_friction.friction = std::nan("");
  EXPECT_FALSE(panel->SetMaterial(nan_friction, &reason));
  EXPECT_TRUE(reason.contains("friction"));

  // Typing a value above the range does not get through the spin box's validator.
  panel->density->selectAll();
  QTest::keyClicks(panel->density, "9");
  QTest::keyClick(panel->density, Qt::Key_Return);
  EXPECT_LE(panel->density->value(), 2.0);
  EXPECT_TRUE(Sent().empty());  // nothing is sent before Apply

  sim::SolverSettings bad;
  bad.tolerance = 1.5;
  EXPECT_FALSE(window_->solver_panel()->SetSettings(bad, &reason));
  EXPECT_TRUE(reason.contains("tolerance"));
}

TEST_F(MainWindowTest, SolverControlsSendSetSolver) {
  SolverPanel* panel = window_->solver_panel();
  panel->method->setCurrentIndex(2);
  EXPECT_TRUE(panel->levels->isEnabled());
  EXPECT_TRUE(panel->coarse_operator->isEnabled());
  panel->coarse_operator->setCurrentIndex(1);
  panel->levels->setValue(3);
  panel->tolerance->setValue(0.001);
  panel->max_iterations->setValue(250);
  panel->substeps->setValue(2);
  panel->apply->click();
  Command c = One();
  EXPECT_EQ(c.kind, Command::KIND_SET_SOLVER);
  EXPECT_EQ(c.solver.method, costume_lcm::solver_parameters::METHOD_MULTIGRID);
  EXPECT_EQ(c.solver.coarse_operator, costume_lcm::solver_parameters::COARSE_GALERKIN);
  EXPECT_EQ(c.solver.levels, 3);
  EXPECT_DOUBLE_EQ(c.solver.tolerance, 0.001);
  EXPECT_EQ(c.solver.max_iterations, 250);
  EXPECT_EQ(c.solver.substeps, 2);

  panel->method->setCurrentIndex(3);
  EXPECT_FALSE(panel->levels->isEnabled());
  EXPECT_FALSE(panel->coarse_operator->isEnabled());
  EXPECT_FALSE(panel->tolerance->isEnabled());
  panel->apply->click();
  EXPECT_EQ(One().solver.method, costume_lcm::solver_parameters::METHOD_DIRECT);
}

// Shown in mm and cm, sent in metres; the map memory only for superquadrics, the step cap
// only while frames may be split.
TEST_F(MainWindowTest, CollisionControlsSendSetCollision) {
  CollisionPanel* panel = window_->collision_panel();
  EXPECT_EQ(panel->method->currentIndex(), 0);  // the scene's (the default: mesh)
  EXPECT_DOUBLE_EQ(panel->thickness_mm->value(), 4.0);
  EXPECT_FALSE(panel->map_memory_mb->isEnabled());
  panel->method->setCurrentIndex(1);
  EXPECT_TRUE(panel->map_memory_mb->isEnabled());
  panel->thickness_mm->setValue(7.0);
  panel->friction->setValue(0.8);
  panel->max_skin_travel_cm->setValue(3.0);
  panel->max_steps_per_frame->setValue(12);
  panel->map_memory_mb->setValue(64.0);
  panel->self_collision->setChecked(true);
  panel->apply->click();
  Command c = One();
  EXPECT_EQ(c.kind, Command::KIND_SET_COLLISION);
  EXPECT_EQ(c.collision.method, costume_lcm::collision_parameters::METHOD_SUPERQUADRIC);
  EXPECT_DOUBLE_EQ(c.collision.thickness, 0.007);
  EXPECT_DOUBLE_EQ(c.collision.friction, 0.8);
  EXPECT_DOUBLE_EQ(c.collision.max_skin_travel, 0.03);
  EXPECT_EQ(c.collision.max_steps_per_frame, 12);
  EXPECT_DOUBLE_EQ(c.collision.superquadric_map_mb, 64.0);
  EXPECT_TRUE(c.collision.self_collision);

  panel->max_skin_travel_cm->setValue(0.0);
  EXPECT_FALSE(panel->max_steps_per_frame->isEnabled());
  panel->method->setCurrentIndex(0);
  panel->apply->click();
  c = One();
  EXPECT_EQ(c.collision.method, costume_lcm::collision_parameters::METHOD_MESH);
  EXPECT_EQ(c.collision.max_skin_travel, 0.0);

  sim::CollisionSettings thick = panel->settings();
  thick.thickness = 0.2;
  QString reason;
  EXPECT_FALSE(panel->SetSettings(thick, &reason));
  EXPECT_TRUE(reason.contains("thickness = 200")) << reason.toStdString();
  EXPECT_DOUBLE_EQ(panel->thickness_mm->value(), 7.0);  // unchanged
}

TEST_F(MainWindowTest, PlaybackAndModeControlsSendTheirKinds) {
  window_->play_action()->trigger();
  EXPECT_EQ(One().kind, Command::KIND_PLAY);
  window_->pause_action()->trigger();
  EXPECT_EQ(One().kind, Command::KIND_PAUSE);
  window_->stop_action()->trigger();
  EXPECT_EQ(One().kind, Command::KIND_STOP);
  window_->editing_mode()->click();
  Command c = One();
  EXPECT_EQ(c.kind, Command::KIND_SET_MODE);
  EXPECT_EQ(c.mode, Command::MODE_EDITING);
  window_->animation_mode()->click();
  c = One();
  EXPECT_EQ(c.kind, Command::KIND_SET_MODE);
  EXPECT_EQ(c.mode, Command::MODE_ANIMATION);
}

TEST_F(MainWindowTest, TheRadiusControlSendsSetSelectionRadiusForARunningHapticServer) {
  window_->radius_box()->setValue(0.12);
  const Command c = One();
  EXPECT_EQ(c.kind, Command::KIND_SET_SELECTION_RADIUS);
  EXPECT_DOUBLE_EQ(c.radius, 0.12);
  // Typed into the box: sent when editing finishes (keyboard tracking off), once.
  window_->radius_box()->clear();
  QTest::keyClicks(window_->radius_box(), "0.3");
  EXPECT_TRUE(Sent().empty());
  QTest::keyClick(window_->radius_box(), Qt::Key_Return);
  const Command typed = One();
  EXPECT_EQ(typed.kind, Command::KIND_SET_SELECTION_RADIUS);
  EXPECT_DOUBLE_EQ(typed.radius, 0.3);
}

TEST_F(MainWindowTest, EditingControlsSendStretchUndoRedoAndSave) {
  window_->radius_box()->setValue(0.12);
  EXPECT_EQ(One().kind, Command::KIND_SET_SELECTION_RADIUS);
  window_->stretch_button()->click();
  const Command c = One();
  EXPECT_EQ(c.kind, Command::KIND_ELIMINATE_STRETCH);
  EXPECT_EQ(c.grab_id, -1);
  EXPECT_DOUBLE_EQ(c.radius, 0.12);
  // No grab and no device yet: the sphere is centred on the cloth's centroid.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3f& p : window_->mirror().rest_positions()) centroid += p.cast<double>();
  centroid /= static_cast<double>(window_->mirror().rest_positions().size());
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(c.centre[i], centroid[i], 1e-6);

  window_->undo_button()->click();
  EXPECT_EQ(One().kind, Command::KIND_UNDO);
  window_->redo_button()->click();
  EXPECT_EQ(One().kind, Command::KIND_REDO);
  window_->version_label()->setText("shorter hem");
  window_->save_button()->click();
  const Command save = One();
  EXPECT_EQ(save.kind, Command::KIND_SAVE_VERSION);
  EXPECT_EQ(save.name, "shorter hem");
}

TEST_F(MainWindowTest, PostureControlsSendSetPosture) {
  PosturePanel* panel = window_->posture_panel();
  panel->angle("l_shoulder", 2)->setValue(-60.0);
  panel->angle("r_knee", 0)->setValue(45.0);
  panel->heading_box()->setValue(30.0);
  panel->apply->click();
  const Command c = One();
  EXPECT_EQ(c.kind, Command::KIND_SET_POSTURE);
  ASSERT_EQ(c.num_joints, static_cast<int>(PostureJoints().size()));
  EXPECT_DOUBLE_EQ(c.heading_degrees, 30.0);
  for (int i = 0; i < c.num_joints; ++i) {
    const std::vector<double> expected =
        c.joint_names[i] == "l_shoulder" ? std::vector<double>{0, 0, -60}
        : c.joint_names[i] == "r_knee"   ? std::vector<double>{45, 0, 0}
                                         : std::vector<double>{0, 0, 0};
    EXPECT_EQ(c.joint_angles[i], expected) << c.joint_names[i];
  }
  // The arms' spread: kept as the scene has it (the simulation's choice by default) until
  // the designer changes the row, then the angles typed, or the simulation's choice again.
  EXPECT_EQ(c.arm_spread_mode, Command::ARM_SPREAD_KEEP);
  EXPECT_TRUE(panel->auto_spread->isChecked());
  EXPECT_FALSE(panel->spread[0]->isEnabled());
  panel->auto_spread->setChecked(false);
  ASSERT_TRUE(panel->spread[0]->isEnabled());
  panel->spread[0]->setValue(12.0);
  panel->spread[1]->setValue(40.0);  // beyond the 30° a scene may ask for: held at it
  panel->apply->click();
  const Command given = One();
  EXPECT_EQ(given.arm_spread_mode, Command::ARM_SPREAD_GIVEN);
  EXPECT_NEAR(given.arm_spread_degrees[0], 12.0, 1e-9);
  EXPECT_NEAR(given.arm_spread_degrees[1], 30.0, 1e-9);
  panel->apply->click();
  EXPECT_EQ(One().arm_spread_mode, Command::ARM_SPREAD_KEEP);
  panel->auto_spread->setChecked(true);
  panel->apply->click();
  EXPECT_EQ(One().arm_spread_mode, Command::ARM_SPREAD_AUTO);
}

// A posture the scene brings (a scene file's [avatar.posture]) shows in the panel, so
// that Apply, say for a new heading, keeps it: the angles shown turn each joint as the
// scene's rotation does (PostureRotation's convention, pose_test), the heading is the turn
// about +y.
TEST(PosturePanelShows, TheScenesPostureSoThatApplyKeepsIt) {
  costume::testing::TestApp();
  PosturePanel panel;
  const sim::Skeleton& skeleton = test::Humanoid()->skeleton();
  sim::Pose posture = sim::RestPose(skeleton);
  const int shoulder = skeleton.Find(sim::HAnimJoint::kLShoulder);
  const int knee = skeleton.Find(sim::HAnimJoint::kRKnee);
  posture.rotations[shoulder] = sim::PostureRotation({0.0, 0.0, -60.0});
  posture.rotations[knee] =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 0.2, 0).normalized()));
  posture.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(-2.0, Eigen::Vector3d::UnitY()));
  panel.SetPosture(posture, skeleton);
  EXPECT_DOUBLE_EQ(panel.angle("l_shoulder", 2)->value(), -60.0);
  EXPECT_DOUBLE_EQ(panel.angle("l_shoulder", 0)->value(), 0.0);
  EXPECT_NEAR(panel.heading(), -2.0 * 180.0 / M_PI, 0.05);  // shown to 0.1°
  for (const JointAngles& joint : panel.joints()) {
    const int index = skeleton.Find(*sim::ParseHAnimName(joint.joint));
    // Shown to 0.1° per axis: within 0.15° of the scene's rotation.
    EXPECT_LT(sim::PostureRotation(joint.degrees).angularDistance(posture.rotations[index]),
              0.0026)
        << joint.joint;
  }
}

TEST_F(MainWindowTest, StatusMessagesUpdateTheStatusBar) {
  costume_lcm::status s{};
  s.utime = bus::NowUtime();
  s.process = "sim_server";
  s.measured_rate = 59.7;
  s.solver_iterations = 17;
  s.frame_time_ms = 8.25;
  s.max_frame_time_ms = 12.5;
  s.frame = 120;
  s.sim_time = 2.0;
  s.mode = costume_lcm::status::MODE_EDITING;
  s.playback = costume_lcm::status::PLAYBACK_PLAYING;
  s.undo_depth = 2;
  s.num_warnings = 1;
  s.warnings = {"LOAD_COSTUME refused: no catalogue"};
  ASSERT_TRUE(bus::Publish(bus_, bus::kSimStatusChannel, s));
  costume_lcm::status h{};
  h.utime = bus::NowUtime();
  h.process = "haptic_server";
  h.measured_rate = 999.6;
  h.period_p99_us = 1019;
  h.warnings = {"loop: 1000 ticks, 0 missed"};  // a once-a-second figure, not a warning
  h.num_warnings = 1;
  ASSERT_TRUE(bus::Publish(bus_, bus::kHapticStatusChannel, h));
  const std::vector<Command> sent_meanwhile = Sent();
  const QString sim = window_->sim_label()->text();
  EXPECT_TRUE(sim.contains("59.7 Hz")) << sim.toStdString();
  EXPECT_TRUE(sim.contains("17 it"));
  EXPECT_TRUE(sim.contains("8.2") || sim.contains("8.3"));
  EXPECT_TRUE(sim.contains("frame 120"));
  EXPECT_TRUE(sim.contains("editing"));
  EXPECT_TRUE(sim.contains("playing"));
  EXPECT_TRUE(window_->editing_mode()->isChecked());  // the switch shows the server's mode
  EXPECT_TRUE(sent_meanwhile.empty());                  // ... without sending a command
  EXPECT_TRUE(sim.contains("undo 2 redo 0"));
  EXPECT_TRUE(window_->undo_button()->toolTip().startsWith("2 edit(s)"));
  EXPECT_EQ(window_->sim_label()->toolTip(), sim);  // whole where a narrow window clips it
  EXPECT_TRUE(window_->warning_label()->text().contains("LOAD_COSTUME refused"));
  // Clipped to the room the figures leave, the warning stays whole in its tooltip.
  EXPECT_EQ(window_->warning_label()->toolTip(), window_->warning_label()->text());
  EXPECT_EQ(window_->warning_label()->sizePolicy().horizontalPolicy(), QSizePolicy::Ignored);
  costume_lcm::feedback f{};
  f.utime = bus::NowUtime();
  f.force[0] = 0.6;
  f.force[1] = -0.8;  // |F| = 1 N
  f.requested_force[2] = 4.0;
  f.clamped = true;
  ASSERT_TRUE(bus::Publish(bus_, bus::kFeedbackChannel, f));
  Sent();
  EXPECT_EQ(window_->force_label()->text(), "force 1.00 N (4.00) clamped");
  const QString haptic = window_->haptic_label()->text();
  EXPECT_TRUE(haptic.contains("1000 Hz")) << haptic.toStdString();
  EXPECT_TRUE(haptic.contains("p99 1019"));
  EXPECT_EQ(window_->haptic_label()->toolTip(), haptic + "\nloop: 1000 ticks, 0 missed");
  EXPECT_FALSE(window_->message_log()->toPlainText().contains("loop: 1000"));
}

/// The mirrored sheet moved by `offset`, sent as `chunks` chunks of frame `frame`.
void PublishFrame(bus::MessageBus& bus, const std::vector<Eigen::Vector3f>& rest,
                  const Eigen::Vector3f& offset, std::int64_t frame, int chunks, int& seq) {
  const int total = static_cast<int>(rest.size());
  const int per_chunk = (total + chunks - 1) / chunks;
  for (int k = 0; k < chunks; ++k) {
    costume_lcm::cloth_frame c{};
    c.utime = bus::NowUtime();
    c.seq = seq++;
    c.frame = frame;
    c.sim_time = frame / 60.0;
    c.total_particles = total;
    c.chunk_index = static_cast<std::int16_t>(k);
    c.num_chunks = static_cast<std::int16_t>(chunks);
    c.first_particle = k * per_chunk;
    c.num_particles = static_cast<std::int16_t>(std::min(per_chunk, total - k * per_chunk));
    for (int i = c.first_particle; i < c.first_particle + c.num_particles; ++i) {
      const Eigen::Vector3f p = rest[i] + offset;
      c.x.push_back(p.x());
      c.y.push_back(p.y());
      c.z.push_back(p.z());
    }
    ASSERT_TRUE(bus::Publish(bus, bus::kClothFrameChannel, c));
  }
}

TEST_F(MainWindowTest, ChunkedClothFramesReachTheView) {
  const auto& rest = window_->mirror().rest_positions();
  int seq = 0;
  const Eigen::Vector3f offset(0.0f, -0.1f, 0.05f);
  PublishFrame(bus_, rest, offset, 5, 3, seq);
  Sent();
  ASSERT_TRUE(window_->last_frame());
  EXPECT_EQ(window_->last_frame()->frame, 5);
  const auto& shown = window_->view().cloth_positions();
  ASSERT_EQ(shown.size(), rest.size());
  for (std::size_t i = 0; i < rest.size(); ++i) {
    ASSERT_TRUE(shown[i].isApprox(rest[i] + offset)) << i;
  }
}

TEST_F(MainWindowTest, MousePressOnTheClothGrabsAndReleaseLetsGo) {
  // Not shown: Qt 6.4's offscreen platform crashes flushing a window with a QOpenGLWidget;
  // the view's picking needs only its size and camera (the Xvfb test drives a real window).
  ViewWidget& view = window_->view();
  view.resize(800, 600);
  // A point of the sheet (the middle particle) and the pixel it projects to.
  const auto& cloth = view.cloth_positions();
  const Eigen::Vector3d target = cloth[cloth.size() / 2].cast<double>();
  const auto pixel = render::ProjectToPixel(view.camera(), target, view.width(), view.height());
  ASSERT_TRUE(pixel);
  const QPoint at(static_cast<int>(pixel->x()), static_cast<int>(pixel->y()));
  QTest::mousePress(&view, Qt::LeftButton, Qt::NoModifier, at);
  ASSERT_TRUE(view.grab_point());
  QTest::mouseMove(&view, at + QPoint(0, 40));
  QTest::mouseRelease(&view, Qt::LeftButton, Qt::NoModifier, at + QPoint(0, 40));
  EXPECT_FALSE(view.grab_point());
  Sent();
  ASSERT_GE(pointer_.size(), 3u);
  const auto& press = pointer_[pointer_.size() - 3];
  const auto& drag = pointer_[pointer_.size() - 2];
  const auto& release = pointer_.back();
  EXPECT_EQ(press.buttons, 1);
  EXPECT_TRUE(press.inside_view);
  // The grab starts on the cloth within a pixel's footprint of the projected particle.
  const Eigen::Vector3d pressed(press.position[0], press.position[1], press.position[2]);
  EXPECT_LT((pressed - target).norm(), 0.02);
  // Dragging 40 px down moves the point down in the plane facing the camera.
  EXPECT_EQ(drag.buttons, 1);
  EXPECT_LT(drag.position[1], press.position[1] - 0.01);
  EXPECT_EQ(release.buttons, 0);
  EXPECT_DOUBLE_EQ(release.position[1], drag.position[1]);
}

// The simulation server repeats a standing warning in every status; the window shows it once,
// so a later warning stays on the status bar and the log is not buried.
TEST_F(MainWindowTest, AStandingWarningIsShownOnce) {
  const std::string standing = "grab acknowledger: SCHED_FIFO priority 70 refused";
  const auto publish = [&](std::vector<std::string> warnings) {
    PublishSimWarnings(bus_, std::move(warnings));
  };
  publish({standing});
  publish({standing, "command UNDO: nothing to undo"});
  publish({standing});
  publish({standing});
  const QString log = window_->message_log()->toPlainText();
  EXPECT_EQ(log.count(QString::fromStdString(standing)), 1) << log.toStdString();
  EXPECT_EQ(log.count("nothing to undo"), 1);
  EXPECT_TRUE(window_->warning_label()->text().contains("nothing to undo"))
      << window_->warning_label()->text().toStdString();
  publish({standing, "command UNDO: nothing to undo"});  // said again later: shown again
  EXPECT_EQ(window_->message_log()->toPlainText().count("nothing to undo"), 2);
}

// A simulation server that stops on its own is reported on the status bar, and Simulation >
// Start server runs it again; the view then follows the start scene. A stand-in program
// plays the server: it exits with code 3, then stays up.
TEST_F(MainWindowTest, AStoppedServerIsReportedAndStartsAgain) {
  const std::filesystem::path bin = std::filesystem::temp_directory_path() /
                                    ("main_window_server_" + std::to_string(::getpid()));
  std::filesystem::create_directories(bin / "sim_core/app");
  const std::filesystem::path program = bin / "sim_core/app/costume_sim_server";
  const auto write_program = [&](const std::string& body) {
    std::ofstream(program) << "#!/bin/sh\n" << body << "\n";
    std::filesystem::permissions(program, std::filesystem::perms::owner_all);
  };
  ChildProcesses& children = window_->children();
  children.options().bin_dir = QString::fromStdString(bin.string());
  write_program("echo 'cannot allocate the cloth'; exit 3");
  window_->start_server_action()->trigger();
  ASSERT_TRUE(
      WaitFor([&] { return window_->warning_label()->text().contains("exit code 3"); }, 10000));
  EXPECT_TRUE(window_->warning_label()->text().contains("Start server"));
  EXPECT_EQ(window_->sim_label()->text(), "sim: not running");
  EXPECT_TRUE(window_->message_log()->toPlainText().contains("cannot allocate the cloth"));

  write_program("exec sleep 30");
  window_->start_server_action()->trigger();
  EXPECT_TRUE(children.sim_running());
  EXPECT_NE(window_->pending_mirror(), nullptr);  // the view follows the fresh server
  EXPECT_TRUE(window_->warning_label()->text().isEmpty());
  children.StopAll();  // stopping it on purpose is not reported
  QTest::qWait(100);
  EXPECT_TRUE(window_->warning_label()->text().isEmpty())
      << window_->warning_label()->text().toStdString();
  std::filesystem::remove_all(bin);
}

// Figures that stopped coming are not shown as current: a status, then none for 3 s.
TEST_F(MainWindowTest, ASilentServerIsShownAsSilent) {
  costume_lcm::status s{};
  s.utime = bus::NowUtime();
  s.measured_rate = 59.9;
  ASSERT_TRUE(bus::Publish(bus_, bus::kSimStatusChannel, s));
  Sent();
  EXPECT_TRUE(window_->sim_label()->text().contains("59.9 Hz"));
  QTest::qWait(1500);
  EXPECT_TRUE(window_->sim_label()->text().contains("59.9 Hz"));  // within a status period
  // It says how long: 3 s, or more when a loaded machine runs the check late.
  ASSERT_TRUE(
      WaitFor([&] { return window_->sim_label()->text().contains("sim: no status for "); }, 10000))
      << window_->sim_label()->text().toStdString();
  EXPECT_TRUE(window_->haptic_label()->text().contains("no status yet"));  // never heard
  s.utime = bus::NowUtime();
  ASSERT_TRUE(bus::Publish(bus_, bus::kSimStatusChannel, s));
  Sent();
  EXPECT_TRUE(window_->sim_label()->text().contains("59.9 Hz"));
}

// A GUI allowed onto the network passes that on: else both servers refuse its URL.
TEST(ChildProcessesArguments, TheNetworkPermissionReachesBothServers) {
  ServerOptions options;
  options.lcm_url = "udpm://239.255.76.67:7667?ttl=1";
  ChildProcesses local(options);
  EXPECT_FALSE(local.SimServerArguments().contains("--allow-network"));
  EXPECT_FALSE(local.HapticServerArguments("mouse").contains("--allow-network"));
  options.allow_network = true;
  ChildProcesses network(options);
  EXPECT_TRUE(network.SimServerArguments().contains("--allow-network"));
  EXPECT_TRUE(network.HapticServerArguments("mouse").contains("--allow-network"));
  EXPECT_TRUE(network.HapticServerArguments("simulated").contains("--allow-network"));
}

// The catalogue URL reaches the children in their environment, never on a command line that
// `ps` shows (it may hold a PostgreSQL password).
TEST(ChildProcessesArguments, TheCatalogueUrlGoesInTheEnvironment) {
  ServerOptions options;
  options.catalog_url = "postgresql://designer:secret@db.example/costumes";
  ChildProcesses children(options);
  EXPECT_EQ(children.ChildEnvironment().value("COSTUME_CATALOG"), options.catalog_url);
  for (const QStringList& args :
       {children.SimServerArguments(), children.HapticServerArguments("mouse")}) {
    EXPECT_FALSE(args.join(' ').contains("secret")) << args.join(' ').toStdString();
  }
}

// A physical device's tip reports around its own origin: its workspace is scaled and moved
// onto the cloth; the mouse and the simulated device report scene positions already.
TEST(ChildProcessesArguments, PhysicalDevicesGetTheirWorkspace) {
  ServerOptions options;
  options.workspace_scale = 3;
  options.workspace_centre = Eigen::Vector3d(0.25, 1.5, -0.125);
  ChildProcesses children(options);
  const QStringList touch = children.HapticServerArguments("openhaptics");
  const qsizetype scale = touch.indexOf("--scale");
  ASSERT_GE(scale, 0);
  EXPECT_EQ(touch.at(scale + 1).toDouble(), 3.0);
  const qsizetype offset = touch.indexOf("--offset");
  ASSERT_GE(offset, 0);
  ASSERT_LT(offset + 3, touch.size());
  EXPECT_EQ(touch.at(offset + 1).toDouble(), 0.25);
  EXPECT_EQ(touch.at(offset + 2).toDouble(), 1.5);
  EXPECT_EQ(touch.at(offset + 3).toDouble(), -0.125);
  EXPECT_TRUE(children.HapticServerArguments("cybergrasp").contains("--offset"));
  for (const QString device : {"mouse", "simulated"}) {
    EXPECT_FALSE(children.HapticServerArguments(device).contains("--offset"));
    EXPECT_FALSE(children.HapticServerArguments(device).contains("--scale"));
  }
}

TEST_F(MainWindowTest, AnUnavailableDeviceShowsTheServersError) {
  ChildProcesses& children = window_->children();
  children.options().bin_dir = COSTUME_BUILD_DIR;
  QString error;
  if (!QFileInfo(children.HapticServerPath()).isExecutable()) {
    GTEST_SKIP() << "costume_haptic_server not built";
  }
  // memq:// keeps the child's traffic inside the child.
  children.options().lcm_url = "memq://";
  window_->device_action("openhaptics")->setChecked(true);
  window_->connect_action()->trigger();
  // Its workspace was centred on the cloth: the mean of the particles the view shows.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  const auto& cloth = window_->view().cloth_positions();
  ASSERT_FALSE(cloth.empty());
  for (const Eigen::Vector3f& p : cloth) centroid += p.cast<double>();
  centroid /= static_cast<double>(cloth.size());
  ASSERT_TRUE(children.options().workspace_centre);
  EXPECT_LT((*children.options().workspace_centre - centroid).norm(), 1e-9);
  EXPECT_TRUE(window_->message_log()->toPlainText().contains("workspace centred on the cloth"));
  ASSERT_TRUE(WaitFor([&] { return !children.device_running(); }, 10000));
  ASSERT_TRUE(WaitFor([&] { return window_->device_label()->text().contains("failed"); }, 5000));
  EXPECT_TRUE(window_->message_log()->toPlainText().contains("openhaptics", Qt::CaseInsensitive))
      << window_->message_log()->toPlainText().toStdString();
}

}  // namespace
}  // namespace costume::frontend

namespace costume::frontend {
namespace {

using costume::testing::WaitFor;

TEST_F(MainWindowTest, DragOnEmptySpaceOrbitsShiftDragPansWheelZooms) {
  ViewWidget& view = window_->view();
  view.resize(800, 600);
  const render::Camera start = view.camera();
  const double distance = (start.eye - start.target).norm();
  // The top-left corner shows no cloth: a left drag there orbits about the target.
  QTest::mousePress(&view, Qt::LeftButton, Qt::NoModifier, QPoint(5, 5));
  EXPECT_FALSE(view.grab_point());
  QTest::mouseMove(&view, QPoint(65, 5));
  QTest::mouseRelease(&view, Qt::LeftButton, Qt::NoModifier, QPoint(65, 5));
  EXPECT_TRUE(view.camera().target.isApprox(start.target));
  EXPECT_NEAR((view.camera().eye - view.camera().target).norm(), distance, 1e-9);
  EXPECT_GT((view.camera().eye - start.eye).norm(), 0.1);
  // Shift + drag pans: eye and target move together.
  const render::Camera orbited = view.camera();
  QTest::mousePress(&view, Qt::LeftButton, Qt::ShiftModifier, QPoint(5, 5));
  QTest::mouseMove(&view, QPoint(5, 65));
  QTest::mouseRelease(&view, Qt::LeftButton, Qt::ShiftModifier, QPoint(5, 65));
  const Eigen::Vector3d moved = view.camera().target - orbited.target;
  EXPECT_GT(moved.norm(), 0.01);
  EXPECT_TRUE((view.camera().eye - orbited.eye).isApprox(moved));
  // One wheel notch towards the scene: the distance shrinks by 10 %.
  const render::Camera panned = view.camera();
  QWheelEvent wheel(QPointF(400, 300), view.mapToGlobal(QPointF(400, 300)), QPoint(),
                    QPoint(0, 120), Qt::NoButton, Qt::NoModifier, Qt::NoScrollPhase, false);
  QApplication::sendEvent(&view, &wheel);
  EXPECT_NEAR((view.camera().eye - view.camera().target).norm(),
              (panned.eye - panned.target).norm() / 1.1, 1e-9);
}

}  // namespace
}  // namespace costume::frontend

namespace costume::frontend {
namespace {

using costume::testing::WaitFor;

TEST(MainWindowLoads, TheViewFollowsALoadedCostumeOnceTheServerRunsIt) {
  costume::testing::TestApp();
  bus::LcmBus bus("memq://");
  FrontendOptions options;  // the garment scene: the skirt on the walking humanoid
  MainWindow window(bus, options, MakeBuiltInCatalog());
  const int skirt = window.mirror().num_particles();
  int seq = 0;
  PublishFrame(bus, window.mirror().rest_positions(), Eigen::Vector3f::Zero(), 10, 1, seq);
  while (bus.HandleSubscriptions(0) > 0) {
  }
  ASSERT_TRUE(window.last_frame());

  QListWidget* costumes = window.list(EntryKind::kCostume);
  costumes->setCurrentItem(costumes->findItems("cape", Qt::MatchExactly).at(0));
  window.load_button(EntryKind::kCostume)->click();
  ASSERT_NE(window.pending_mirror(), nullptr);
  const int cape = window.pending_mirror()->num_particles();
  ASSERT_NE(cape, skirt);
  EXPECT_EQ(window.mirror().num_particles(), skirt);  // until the server shows the cape
  // Building the copy can take seconds (MakeHuman's suit with a motion-capture clip): the
  // log says how long, and the busy cursor is gone once it is built.
  const QRegularExpression built(
      QString("new scene \\(%1 particles; its copy built in \\d+\\.\\d s\\)").arg(cape));
  EXPECT_TRUE(window.message_log()->toPlainText().contains(built))
      << window.message_log()->toPlainText().toStdString();
  EXPECT_EQ(QGuiApplication::overrideCursor(), nullptr);

  // The server refuses: the view keeps the skirt.
  PublishSimWarnings(bus,
                     {"command LOAD_COSTUME: not available until the database issue; ignored"});
  EXPECT_EQ(window.pending_mirror(), nullptr);

  // Loaded again and accepted: the server's frames start again at 0 with the cape.
  window.load_button(EntryKind::kCostume)->click();
  ASSERT_NE(window.pending_mirror(), nullptr);
  const std::vector<Eigen::Vector3f> cape_rest = window.pending_mirror()->rest_positions();
  PublishFrame(bus, cape_rest, Eigen::Vector3f::Zero(), 0, 1, seq);
  while (bus.HandleSubscriptions(0) > 0) {
  }
  EXPECT_EQ(window.pending_mirror(), nullptr);
  EXPECT_EQ(window.mirror().num_particles(), cape);
  EXPECT_EQ(static_cast<int>(window.view().cloth_positions().size()), cape);
  EXPECT_EQ(window.last_frame()->frame, 0);
}

// The server keeps SET_SOLVER's and SET_COLLISION's settings through a load (it loads into
// its scene); the mirror does too, and the tabs show the loaded scene's settings.
TEST(MainWindowLoads, ALoadedSceneKeepsTheSettingsSentBeforeIt) {
  costume::testing::TestApp();
  bus::LcmBus bus("memq://");
  MainWindow window(bus, FrontendOptions{}, MakeBuiltInCatalog());
  CollisionPanel* collision = window.collision_panel();
  collision->thickness_mm->setValue(7.0);
  collision->self_collision->setChecked(true);
  collision->apply->click();
  window.solver_panel()->substeps->setValue(3);
  window.solver_panel()->apply->click();
  EXPECT_DOUBLE_EQ(window.mirror().scene().avatar->thickness, 0.007);

  QListWidget* costumes = window.list(EntryKind::kCostume);
  costumes->setCurrentItem(costumes->findItems("cape", Qt::MatchExactly).at(0));
  window.load_button(EntryKind::kCostume)->click();
  ASSERT_NE(window.pending_mirror(), nullptr);
  collision->friction->setValue(0.9);  // sent while the load is pending: the load keeps it
  collision->apply->click();
  int seq = 0;
  PublishFrame(bus, window.pending_mirror()->rest_positions(), Eigen::Vector3f::Zero(), 0, 1,
               seq);
  while (bus.HandleSubscriptions(0) > 0) {
  }
  ASSERT_EQ(window.pending_mirror(), nullptr);
  const sim::SceneDescription& scene = window.mirror().scene();
  EXPECT_EQ(scene.garments.front().pattern, "cape");
  EXPECT_DOUBLE_EQ(scene.avatar->thickness, 0.007);
  EXPECT_DOUBLE_EQ(scene.avatar->friction, 0.9);
  EXPECT_TRUE(scene.effects.self_collision);
  EXPECT_EQ(scene.solver.substeps, 3);
  EXPECT_DOUBLE_EQ(collision->thickness_mm->value(), 7.0);
  EXPECT_DOUBLE_EQ(collision->friction->value(), 0.9);
  EXPECT_EQ(window.solver_panel()->substeps->value(), 3);
}

}  // namespace
}  // namespace costume::frontend

#ifdef COSTUME_HAVE_CATALOG
namespace costume::frontend {
namespace {

using costume::testing::WaitFor;

/// A window on a SQLite catalogue of its own, in a temporary folder removed afterwards, with
/// the built programs for its children (thumbnails, imports), as costume_designer --catalog.
class MainWindowCatalogue : public ::testing::Test {
 protected:
  void SetUp() override {
    costume::testing::TestApp();
    dir_ = std::filesystem::temp_directory_path() /
           ("main_window_catalogue_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    url_ = "sqlite:" + (dir_ / "c.sqlite").string();
  }
  void TearDown() override {
    window_.reset();
    std::filesystem::remove_all(dir_);
  }

  /// Opens the window; false when costume-catalog is not built (the test then skips).
  bool OpenWindow() {
    FrontendOptions options;
    options.builtin = "hang";
    options.servers.bin_dir = COSTUME_BUILD_DIR;
    options.servers.catalog_url = QString::fromStdString(url_);
    std::string warning;
    window_ = std::make_unique<MainWindow>(bus_, options, OpenCatalogSource(url_, &warning));
    EXPECT_TRUE(warning.empty()) << warning;
    return QFileInfo(window_->children().CatalogProgramPath()).isExecutable();
  }

  /// Writes `text` to the catalogue's folder as `name`; returns its path.
  QString Write(const std::string& name, const std::string& text) {
    std::filesystem::create_directories((dir_ / name).parent_path());
    std::ofstream(dir_ / name) << text;
    return QString::fromStdString((dir_ / name).string());
  }

  std::string Log() const { return window_->message_log()->toPlainText().toStdString(); }

  std::filesystem::path dir_;
  std::string url_;
  bus::LcmBus bus_{"memq://"};
  std::unique_ptr<MainWindow> window_;
};

// A catalogue without thumbnails (made with --no-thumbnails; a version the simulation server
// saved) gets them from a child `costume-catalog thumbnails`, and the lists show them without
// losing the designer's pick.
TEST_F(MainWindowCatalogue, MissingThumbnailsAreRenderedByAChildAndListed) {
  auto db = catalog::Catalog::Open(url_);  // seeded without a renderer: no thumbnails
  const std::int64_t skirt = db->Find(catalog::Kind::kGarment, "skirt")->id;
  ASSERT_TRUE(db->Thumbnail(skirt).empty());
  if (!OpenWindow()) GTEST_SKIP() << "costume-catalog not built";
  MainWindow& window = *window_;
  EXPECT_TRUE(window.lists_lack_thumbnails());
  QListWidget* costumes = window.list(EntryKind::kCostume);
  costumes->setCurrentItem(costumes->findItems("skirt", Qt::MatchExactly).at(0));

  window.StartChildren();
  ASSERT_TRUE(WaitFor(
      [&] { return window.message_log()->toPlainText().contains("thumbnails made"); }, 60000));
  EXPECT_FALSE(window.lists_lack_thumbnails()) << Log();
  EXPECT_FALSE(db->Thumbnail(skirt).empty());
  ASSERT_NE(costumes->currentItem(), nullptr);
  EXPECT_EQ(costumes->currentItem()->text(), "skirt");

  // The server saves a version (it renders no thumbnail) and says so: the lists are filled
  // again and the new version's picture is made.
  db->SaveGarmentVersion(skirt, db->Data(skirt), "edited", {});
  EXPECT_TRUE(db->Thumbnail(skirt).empty());
  PublishSimWarnings(bus_, {"command SAVE_VERSION: saved garment 'skirt' version 2 'edited'"});
  ASSERT_TRUE(WaitFor(
      [&] { return window.message_log()->toPlainText().count("thumbnails made") == 2; }, 60000));
  EXPECT_FALSE(window.lists_lack_thumbnails());
  EXPECT_FALSE(db->Thumbnail(skirt).empty());
  EXPECT_EQ(costumes->currentItem()->text(), "skirt");
}

// File → Import …: the picked files go to a child `costume-catalog import`; what it stores is
// listed, with its thumbnail. A bad file is refused with its name and what is wrong, in the
// status bar's warning, and nothing of that batch is stored.
TEST_F(MainWindowCatalogue, FilesImportedFromTheFileMenuAreListed) {
  const QString scarf = Write("garments/scarf.toml",
                              "[[garment]]\nname = \"scarf\"\n[garment.panel]\n"
                              "origin = [0, 1, 0]\nu_axis = [1, 0, 0]\nv_axis = [0, 0, 1]\n"
                              "size = [0.2, 1.0]\nresolution = [5, 17]\n");
  const QString bad = Write("garments/bad.toml",
                            "[[garment]]\nname = \"bad\"\n[garment.panel]\n"
                            "size = [-1, 1]\n");
  if (!OpenWindow()) GTEST_SKIP() << "costume-catalog not built";
  MainWindow& window = *window_;
  ASSERT_TRUE(window.import_action(EntryKind::kCostume)->isEnabled());
  QListWidget* costumes = window.list(EntryKind::kCostume);
  const int listed = costumes->count();

  window.ImportFiles(EntryKind::kCostume, {scarf, bad});
  ASSERT_TRUE(WaitFor(
      [&] { return window.warning_label()->text().contains("nothing was imported"); }, 60000))
      << Log();
  const std::string refusal = window.warning_label()->text().toStdString();
  EXPECT_NE(refusal.find("bad.toml"), std::string::npos) << refusal;
  EXPECT_NE(refusal.find("size"), std::string::npos) << refusal;
  EXPECT_EQ(costumes->count(), listed);

  window.ImportFiles(EntryKind::kCostume, {scarf});
  ASSERT_TRUE(WaitFor([&] { return costumes->count() == listed + 1; }, 60000));
  const QList<QListWidgetItem*> found = costumes->findItems("scarf", Qt::MatchExactly);
  ASSERT_EQ(found.size(), 1);
  ASSERT_NE(costumes->currentItem(), nullptr);
  EXPECT_EQ(costumes->currentItem()->text(), "scarf");  // picked: Load takes it at once
  // Removed again (the context menu's action, after its confirmation); built-ins stay.
  EXPECT_TRUE(window.RemoveEntry(EntryKind::kCostume, "scarf"));
  EXPECT_EQ(costumes->count(), listed);
  EXPECT_FALSE(window.RemoveEntry(EntryKind::kCostume, "skirt"));
  EXPECT_TRUE(window.warning_label()->text().contains("built in"))
      << window.warning_label()->text().toStdString();
  EXPECT_EQ(costumes->count(), listed);
  EXPECT_NE(Log().find("catalogue: [1/1]"), std::string::npos) << Log();  // its progress line
  EXPECT_FALSE(window.lists_lack_thumbnails()) << "the import renders the scarf's thumbnail";
}

// A MakeHuman suit picked with the body it is fitted to is imported and listed with its
// thumbnail (on that body).
TEST_F(MainWindowCatalogue, AMakeHumanSuitPickedWithItsBodyIsImported) {
  const std::filesystem::path mh = std::filesystem::absolute(test::kSharedData / "makehuman");
  const std::filesystem::path suit = mh / "clothes/male_casualsuit02/male_casualsuit02.mhclo";
  if (!std::filesystem::exists(suit)) GTEST_SKIP() << suit << " is absent";
  if (!OpenWindow()) GTEST_SKIP() << "costume-catalog not built";
  MainWindow& window = *window_;
  auto path = [](const std::filesystem::path& p) { return QString::fromStdString(p.string()); };
  // Alone, out of MakeHuman's folders: its body cannot be found, and the warning says how to
  // give it here.
  std::filesystem::create_directories(dir_ / "lone");
  std::filesystem::copy_file(suit, dir_ / "lone/male_casualsuit02.mhclo");
  std::filesystem::copy_file(suit.parent_path() / "male_casualsuit02.obj",
                             dir_ / "lone/male_casualsuit02.obj");
  window.ImportFiles(EntryKind::kCostume, {path(dir_ / "lone/male_casualsuit02.mhclo")});
  QLabel* label = window.warning_label();
  ASSERT_TRUE(WaitFor([&] { return label->text().contains("nothing was imported"); }, 60000));
  EXPECT_TRUE(label->text().contains("pick the garment together with its body"))
      << label->text().toStdString();
  window.ImportFiles(EntryKind::kCostume,
                     {path(suit), path(mh / "body/base.obj"), path(mh / "body/default.mhskel"),
                      path(mh / "body/default_weights.mhw")});
  QListWidget* costumes = window.list(EntryKind::kCostume);
  ASSERT_TRUE(WaitFor(
      [&] { return !costumes->findItems("male_casualsuit02", Qt::MatchExactly).isEmpty(); },
      60000))
      << Log();
  EXPECT_FALSE(window.lists_lack_thumbnails());
}

// The import folder holds every picked file, and a MakeHuman garment's body two levels up.
TEST(ImportRoot, IsTheDeepestFolderHoldingThemAll) {
  EXPECT_EQ(ImportRoot({"/data/a/x.bvh", "/data/a/y.bvh"}), "/data/a");
  EXPECT_EQ(ImportRoot({"/data/a/x.bvh", "/data/ab/y.bvh"}), "/data");  // not "/data/a"
  EXPECT_EQ(ImportRoot({"/data/a/b/x.bvh", "/data/a/y.bvh"}), "/data/a");
  EXPECT_EQ(ImportRoot({"/mh/clothes/suit/suit.mhclo"}), "/mh");
  EXPECT_EQ(ImportRoot({"/x/a.bvh", "/y/b.bvh"}), "/");
}

// Picked beside MakeHuman garments, the body's files say which body they are fitted to; an
// avatar's .obj, .mhskel and .mhw stay entries (MakeHuman's avatar triple).
TEST(ImportArguments, GiveAMakeHumanGarmentsBodyAsOptions) {
  EXPECT_EQ(ImportArguments("garment", {"/mh/clothes/s/s.mhclo", "/mh/b/base.obj",
                                        "/mh/b/default.mhskel", "/mh/b/w.mhw"}),
            (QStringList{"--kind", "garment", "--root", "/mh", "--makehuman-body", "/mh/b/base.obj",
                         "--makehuman-skeleton", "/mh/b/default.mhskel", "--makehuman-weights",
                         "/mh/b/w.mhw", "--", "/mh/clothes/s/s.mhclo"}));
  EXPECT_EQ(ImportArguments("avatar", {"/mh/b/base.obj", "/mh/b/default.mhskel", "/mh/b/w.mhw"}),
            (QStringList{"--kind", "avatar", "--root", "/mh/b", "--", "/mh/b/base.obj",
                         "/mh/b/default.mhskel", "/mh/b/w.mhw"}));
  EXPECT_EQ(ImportArguments("garment", {"/g/-x.toml"}),
            (QStringList{"--kind", "garment", "--root", "/g", "--", "/g/-x.toml"}));
}

// The dialog's filters are the import's extensions; each file of the MakeHuman body its
// second garment filter offers is passed as that body's option, not as a garment.
TEST(ImportFilter, OffersTheImportsExtensionsAndTheBodyFilesBecomeOptions) {
  const QString avatars = QString::fromStdString(ImportFilter(EntryKind::kAvatar));
  for (const char* e : {"*.glb", "*.vrm", "*.obj", "*.mhskel", "*.mhw"}) {
    EXPECT_TRUE(avatars.contains(e)) << avatars.toStdString() << " lacks " << e;
  }
  const QStringList garments =
      QString::fromStdString(ImportFilter(EntryKind::kCostume)).split(";;");
  ASSERT_EQ(garments.size(), 2);
  const QRegularExpression pattern(R"(\*\.(\w+))");
  QStringList picked;
  for (const QRegularExpressionMatch& m : pattern.globalMatch(garments[1])) {
    picked << "/mh/f/x." + m.captured(1);
  }
  ASSERT_TRUE(picked.contains("/mh/f/x.mhclo")) << garments[1].toStdString();
  const QStringList arguments = ImportArguments("garment", picked);
  const QStringList entries = arguments.mid(arguments.indexOf("--") + 1);
  EXPECT_EQ(entries, QStringList{"/mh/f/x.mhclo"}) << arguments.join(' ').toStdString();
  EXPECT_TRUE(QString::fromStdString(ImportFilter(EntryKind::kAnimation)).contains("*.bvh"));
}

}  // namespace
}  // namespace costume::frontend
#endif
