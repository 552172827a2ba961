// The workstation in a real window (label integration): under Xvfb (X11, Mesa's OpenGL 3.3
// core), inside a private network namespace, the GUI starts the real simulation server on
// the garment scene and the haptic server with the mouse device; the test plays 2 s of the
// walk, switches to editing, grabs the skirt with synthesized mouse events, drags and
// releases it, presses "eliminate stretch energy", saves a screenshot of the 3D view and
// checks that the avatar and the cloth are where the view's camera projects them.
// Run through ctest (tests/integration/designer_window.sh sets up Xvfb and the namespace).
#include <QDir>
#include <QFile>
#include <QSignalSpy>
#include <QFileInfo>
#include <QTest>
#include <gtest/gtest.h>

#include <sstream>
#include <utility>

#include <cstdio>
#include <cstdlib>

#include "bus/lcm_bus.h"
#include "frontend/main_window.h"
#include "render/camera.h"
#include "tests/support/network_namespace.h"
#include "tests/support/qt_app.h"

namespace costume::frontend {
namespace {

using costume::testing::InNetworkNamespace;
using costume::testing::WaitFor;

/// The colour at `pixel` of `image` as RGB in [0, 1].
Eigen::Vector3f ColourAt(const QImage& image, const Eigen::Vector2d& pixel) {
  const QColor c = image.pixelColor(static_cast<int>(pixel.x()), static_cast<int>(pixel.y()));
  return Eigen::Vector3f(c.redF(), c.greenF(), c.blueF());
}

/// Lit skin: red well above blue. Lit cloth: blue well above red. Background: light grey.
bool LooksLikeSkin(const Eigen::Vector3f& c) { return c.x() > c.z() + 0.1f; }
bool LooksLikeCloth(const Eigen::Vector3f& c) { return c.z() > c.x() + 0.2f; }
bool LooksLikeBackground(const Eigen::Vector3f& c, const Eigen::Vector3f& background) {
  return (c - background).cwiseAbs().maxCoeff() < 0.06f;
}

/// Fraction of `points` [m] whose pixel in `image`, or one within `reach` pixels of it, passes
/// `test` (a vertex on a mesh's outline may fall just outside the pixels its triangles cover).
template <class Test>
double FractionMatching(const QImage& image, const render::Camera& camera,
                        const std::vector<Eigen::Vector3d>& points, Test test, int reach = 0) {
  int inside = 0, matching = 0;
  for (const Eigen::Vector3d& p : points) {
    const auto pixel = render::ProjectToPixel(camera, p, image.width(), image.height());
    if (!pixel || pixel->x() < 0 || pixel->y() < 0 || pixel->x() >= image.width() ||
        pixel->y() >= image.height()) {
      continue;
    }
    ++inside;
    bool found = false;
    for (int dy = -reach; dy <= reach && !found; ++dy) {
      for (int dx = -reach; dx <= reach && !found; ++dx) {
        const Eigen::Vector2d near = *pixel + Eigen::Vector2d(dx, dy);
        const bool on_image = near.x() >= 0 && near.y() >= 0 && near.x() < image.width() &&
                              near.y() < image.height();
        found = on_image && test(ColourAt(image, near));
      }
    }
    if (found) ++matching;
  }
  return inside == 0 ? 0.0 : static_cast<double>(matching) / inside;
}

/// The lowest and highest y of `points` [m].
std::pair<float, float> HeightRange(const std::vector<Eigen::Vector3f>& points) {
  float low = 1e9f, high = -1e9f;
  for (const auto& p : points) {
    low = std::min(low, p.y());
    high = std::max(high, p.y());
  }
  return {low, high};
}

/// Centre of the avatar's head: the mean of the vertices within 12 cm of the top [m].
Eigen::Vector3d HeadCentre(const std::vector<Eigen::Vector3f>& vertices) {
  float top = -1e9f;
  for (const auto& v : vertices) top = std::max(top, v.y());
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (const auto& v : vertices) {
    if (v.y() > top - 0.12f) {
      sum += v.cast<double>();
      ++n;
    }
  }
  return sum / std::max(1, n);
}

/// Whether something covers `p` [m] seen from `eye`: one of `points` within `clearance` [m]
/// of the line of sight and less than `beyond` [m] past `p` along it (skin vertices, 1–2 cm
/// apart: 2 cm, and −1 cm, i.e. in front of p; the selection sphere, which tints the cloth
/// inside it too, and the cursor: their size, and as far past p).
bool HiddenBy(const Eigen::Vector3d& eye, const Eigen::Vector3d& p,
              const std::vector<Eigen::Vector3f>& points, double clearance, double beyond) {
  const Eigen::Vector3d ray = p - eye;
  const double length = ray.norm();
  const Eigen::Vector3d dir = ray / length;
  for (const Eigen::Vector3f& v : points) {
    const Eigen::Vector3d w = v.cast<double>() - eye;
    const double along = w.dot(dir);
    if (along <= 0.0 || along >= length + beyond) continue;
    if ((w - along * dir).norm() < clearance) return true;
  }
  return false;
}

TEST(DesignerWindow, WalkGrabStretchAndScreenshot) {
  if (!InNetworkNamespace()) GTEST_SKIP() << "run through ctest: it needs Xvfb and a network namespace";
  costume::testing::TestApp();
  // A stand-in ffmpeg first on PATH (this machine has none): records its arguments and
  // writes the video file, so the export's video step runs end to end.
  const QString stub_dir = QString(COSTUME_BUILD_DIR) + "/designer_window_ffmpeg";
  QDir().mkpath(stub_dir);
  {
    QFile stub(stub_dir + "/ffmpeg");
    ASSERT_TRUE(stub.open(QIODevice::WriteOnly));
    stub.write("#!/bin/sh\necho \"$@\" > ffmpeg_args.txt\nfor last; do :; done\n"
               "ls frame_00000.png >/dev/null && echo video > \"$last\"\n");
    stub.setPermissions(stub.permissions() | QFileDevice::ExeOwner);
  }
  qputenv("PATH", (stub_dir + ":").toUtf8() + qgetenv("PATH"));
  bus::LcmBus bus(bus::kDefaultLcmUrl);
  FrontendOptions options;
  options.builtin = "garment";
  options.start_sim_server = true;
  options.device = "mouse";
  options.servers.bin_dir = COSTUME_BUILD_DIR;
  options.servers.lcm_url = QString::fromStdString(bus.url());
  options.servers.builtin = "garment";
  options.servers.radius = 0.06;
  MainWindow window(bus, options, MakeBuiltInCatalog());
  window.resize(1280, 780);
  window.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&window));
  window.StartBusThread();
  window.StartChildren();
  ViewWidget& view = window.view();
  ASSERT_TRUE(view.gl_info().startsWith("3.") || view.gl_info().startsWith("4."))
      << view.gl_info().toStdString();

  // 2 s of the walk after the 0.5 s fitting, exported as PNG frames from 1 s on.
  ASSERT_TRUE(WaitFor([&] { return window.last_frame().has_value(); }, 60000));
  ASSERT_TRUE(WaitFor([&] { return window.last_frame()->sim_time >= 1.0; }, 120000));
  const QString export_dir = QString(COSTUME_BUILD_DIR) + "/designer_window_export";
  QDir(export_dir).removeRecursively();
  ASSERT_TRUE(window.exporter().Start(export_dir));
  ASSERT_TRUE(WaitFor([&] { return window.last_frame()->sim_time >= 2.5; }, 120000));
  QSignalSpy video(&window.exporter(), &FrameExporter::videoDone);
  EXPECT_TRUE(window.exporter().Finish().contains("encoding animation.mp4"));
  ASSERT_TRUE(WaitFor([&] { return video.count() == 1; }, 10000));
  EXPECT_TRUE(video.at(0).at(0).toString().startsWith("video written"));
  EXPECT_TRUE(QFileInfo(export_dir + "/animation.mp4").isFile());
  QFile args(export_dir + "/ffmpeg_args.txt");
  ASSERT_TRUE(args.open(QIODevice::ReadOnly));
  EXPECT_TRUE(args.readAll().contains("-framerate 60 -i frame_%05d.png"));
  const int exported = window.exporter().frames_written();
  EXPECT_GE(exported, 10);  // 1.5 s of frames; fewer drawn than received on a loaded machine
  EXPECT_TRUE(QFileInfo(export_dir + "/frame_00000.png").isFile());
  EXPECT_TRUE(QFileInfo(export_dir + QString("/frame_%1.png").arg(exported - 1, 5, 10, QChar('0')))
                  .isFile());
  EXPECT_FALSE(window.last_frame()->editing);
  const double walked = window.mirror().avatar_time();
  EXPECT_GE(walked, 2.5);

  // Mode B: the avatar stops, the cloth keeps simulating and takes grabs.
  window.editing_mode()->click();
  ASSERT_TRUE(WaitFor([&] { return window.last_frame()->editing; }, 10000));
  QTest::qWait(500);
  EXPECT_NEAR(window.mirror().avatar_time(), walked, 0.2);

  // Grab the skirt's front, at the particle nearest the camera at the middle of the skirt.
  const std::vector<Eigen::Vector3f> before = view.cloth_positions();
  const auto [y_min, y_max] = HeightRange(before);
  const float y_mid = 0.5f * (y_min + y_max);
  int front = -1;
  double nearest = 1e9;
  for (int i = 0; i < static_cast<int>(before.size()); ++i) {
    if (std::abs(before[i].y() - y_mid) > 0.05f) continue;
    const double d = (before[i].cast<double>() - view.camera().eye).norm();
    if (d < nearest) {
      nearest = d;
      front = i;
    }
  }
  ASSERT_GE(front, 0);
  const auto pixel =
      render::ProjectToPixel(view.camera(), before[front].cast<double>(), view.width(), view.height());
  ASSERT_TRUE(pixel);
  const QPoint at(static_cast<int>(pixel->x()), static_cast<int>(pixel->y()));
  QTest::mouseMove(&view, at);
  QTest::qWait(200);
  QTest::mousePress(&view, Qt::LeftButton, Qt::NoModifier, at);
  ASSERT_TRUE(view.grab_point()) << "the press did not hit the cloth";
  const Eigen::Vector3d grabbed = *view.grab_point();
  for (int step = 1; step <= 10; ++step) {  // 40 px to the right, slowly
    QTest::mouseMove(&view, at + QPoint(4 * step, 0));
    QTest::qWait(60);
  }
  // Hold for 1 s of simulated time, not wall time: a loaded machine simulates slower, and the
  // particle needs the simulated second to follow the pointer.
  const double held_from = window.last_frame()->sim_time;
  ASSERT_TRUE(WaitFor([&] { return window.last_frame()->sim_time >= held_from + 1.0; }, 60000));
  const Eigen::Vector3d pulled_to = *view.grab_point();
  const std::vector<Eigen::Vector3f> held = view.cloth_positions();
  QTest::mouseRelease(&view, Qt::LeftButton, Qt::NoModifier, at + QPoint(40, 0));
  // The grabbed particle followed the pointer along the drag.
  const Eigen::Vector3d drag = pulled_to - grabbed;
  ASSERT_GT(drag.norm(), 0.02);
  const double moved = (held[front] - before[front]).cast<double>().dot(drag.normalized());
  EXPECT_GT(moved, 0.3 * drag.norm()) << "drag " << drag.norm() << " m, particle moved " << moved;
  std::printf("exported %d PNG frames; walked %.2f s; pointer dragged %.1f cm, grabbed particle moved %.1f cm along it\n",
              exported, walked, 100.0 * drag.norm(), 100.0 * moved);

  // "Eliminate stretch energy" at the grab: an edit the server can undo.
  window.stretch_button()->click();
  ASSERT_TRUE(WaitFor([&] { return window.sim_label()->text().contains("undo 1"); }, 10000));
  QTest::qWait(300);

  // The screenshot: the avatar's head and the skirt where the camera puts them.
  const QImage shot = view.grabFramebuffer();
  const QString path = QString(COSTUME_BUILD_DIR) + "/designer_window_test.png";
  ASSERT_TRUE(shot.save(path)) << path.toStdString();
  const render::Camera& camera = view.camera();
  ASSERT_EQ(shot.width(), static_cast<int>(std::lround(view.width() * view.devicePixelRatioF())));
  const auto& avatar = window.mirror().avatar_vertices();
  const Eigen::Vector3d head = HeadCentre(avatar);
  EXPECT_EQ(FractionMatching(shot, camera, {head}, LooksLikeSkin), 1.0) << "head at "
      << head.transpose();
  // Skirt points facing the camera at several heights and sides: away from the grab, not
  // behind the walking avatar's swinging hands, and not behind the selection sphere and
  // cursor drawn over the cloth (a point behind the sphere failed 1 run in 7).
  const std::vector<Eigen::Vector3f> cloth = view.cloth_positions();
  std::vector<Eigen::Vector3f> overlays;  // the sphere's and cursor's centres, with clearance below
  double overlay_clearance = 0.0;
  const render::RenderScene drawn = view.BuildScene();
  if (drawn.selection) {
    overlays.push_back(drawn.selection->centre.cast<float>());
    overlay_clearance = std::max(overlay_clearance, drawn.selection->radius + 0.02);
  }
  if (drawn.cursor) {
    overlays.push_back(drawn.cursor->position.cast<float>());
    overlay_clearance = std::max(overlay_clearance, drawn.cursor->size + 0.02);
  }
  // Heights from the cloth as drawn now: the grab and the edit have moved it since `before`,
  // and a band placed from the old extent could hold the hem, whose vertices lie on the
  // mesh's edge, where a pixel may show the background (a sample did, once in about 20 runs).
  const auto [now_min, now_max] = HeightRange(cloth);
  std::vector<Eigen::Vector3d> skirt;
  for (float t : {0.3f, 0.5f, 0.75f}) {
    const float y = now_min + t * (now_max - now_min);
    int best = -1;
    double best_d = 1e9;
    for (int i = 0; i < static_cast<int>(cloth.size()); ++i) {
      if (std::abs(cloth[i].y() - y) > 0.03f) continue;
      if ((cloth[i].cast<double>() - grabbed).norm() < 0.15) continue;
      if (HiddenBy(camera.eye, cloth[i].cast<double>(), avatar, 0.02, -0.01)) continue;
      if (HiddenBy(camera.eye, cloth[i].cast<double>(), overlays, overlay_clearance,
                   overlay_clearance)) {
        continue;
      }
      const double d = (cloth[i].cast<double>() - camera.eye).norm();
      if (d < best_d) {
        best_d = d;
        best = i;
      }
    }
    if (best >= 0) skirt.push_back(cloth[best].cast<double>());
  }
  ASSERT_GE(skirt.size(), 2u);
  EXPECT_EQ(FractionMatching(shot, camera, skirt, LooksLikeCloth, 1), 1.0) << [&] {
    std::ostringstream seen;  // what each point's pixel shows, to tell what covered it
    for (const Eigen::Vector3d& p : skirt) {
      const auto at_pixel = render::ProjectToPixel(camera, p, shot.width(), shot.height());
      seen << "point " << p.transpose() << " pixel ";
      if (at_pixel) seen << at_pixel->transpose() << " colour " << ColourAt(shot, *at_pixel).transpose() << "; ";
    }
    return seen.str();
  }();
  // The top corners show the background.
  const Eigen::Vector3f background = ViewColours{}.background;
  EXPECT_TRUE(LooksLikeBackground(ColourAt(shot, {4, 4}), background));
  EXPECT_TRUE(LooksLikeBackground(ColourAt(shot, {shot.width() - 5.0, 4}), background));
  window.close();
  EXPECT_FALSE(window.children().sim_running());
  EXPECT_FALSE(window.children().device_running());
}

TEST(DesignerWindow, DoubleClickingACostumeLoadsItOnTheServerAndInTheView) {
  if (!InNetworkNamespace()) GTEST_SKIP() << "run through ctest: it needs Xvfb and a network namespace";
  costume::testing::TestApp();
  // A fresh catalogue, seeded with the built-ins, shared by the lists and the server.
  const QString folder = QString(COSTUME_BUILD_DIR) + "/designer_window_catalog";
  QDir(folder).removeRecursively();
  QDir().mkpath(folder);
  const std::string url = "sqlite:" + (folder + "/catalog.sqlite").toStdString();
  std::string warning;
  auto catalog = OpenCatalogSource(url, &warning);
  ASSERT_TRUE(warning.empty()) << warning;
  bus::LcmBus bus(bus::kDefaultLcmUrl);
  FrontendOptions options;
  options.start_sim_server = true;
  options.servers.bin_dir = COSTUME_BUILD_DIR;
  options.servers.lcm_url = QString::fromStdString(bus.url());
  options.servers.catalog_url = QString::fromStdString(url);
  MainWindow window(bus, options, std::move(catalog));
  window.resize(1280, 780);
  window.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&window));
  window.StartBusThread();
  window.StartChildren();
  const int skirt = window.mirror().num_particles();
  ASSERT_TRUE(WaitFor([&] { return window.last_frame().has_value(); }, 60000));
  ASSERT_TRUE(WaitFor([&] { return window.last_frame()->frame >= 30; }, 60000));

  QListWidget* costumes = window.list(EntryKind::kCostume);
  const QList<QListWidgetItem*> cape = costumes->findItems("cape", Qt::MatchExactly);
  ASSERT_EQ(cape.size(), 1);
  costumes->scrollToItem(cape[0]);
  const QPoint at = costumes->visualItemRect(cape[0]).center();
  QTest::mouseClick(costumes->viewport(), Qt::LeftButton, Qt::NoModifier, at);
  QTest::mouseDClick(costumes->viewport(), Qt::LeftButton, Qt::NoModifier, at);
  ASSERT_TRUE(WaitFor(
      [&] {
        return window.pending_mirror() != nullptr || window.mirror().num_particles() != skirt;
      },
      5000));
  // The server rebuilds with the cape (a second or so) and its frames start again at 0.
  ASSERT_TRUE(WaitFor([&] { return window.mirror().num_particles() != skirt; }, 60000));
  EXPECT_EQ(window.pending_mirror(), nullptr);
  ASSERT_TRUE(WaitFor(
      [&] {
        return static_cast<int>(window.view().cloth_positions().size()) ==
               window.mirror().num_particles();
      },
      10000));
  EXPECT_FALSE(window.message_log()->toPlainText().contains("refused"))
      << window.message_log()->toPlainText().toStdString();
  std::printf("cape loaded: %d particles (skirt %d)\n", window.mirror().num_particles(), skirt);
  window.close();
}

}  // namespace
}  // namespace costume::frontend
