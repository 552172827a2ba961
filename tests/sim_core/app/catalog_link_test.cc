// The simulation server's catalogue commands on memq://, with a SQLite catalogue in a temp
// folder: LOAD_AVATAR, LOAD_COSTUME and LOAD_ANIMATION by id and by name change what is
// simulated; refusals keep the old simulation; SAVE_VERSION after a stretch-elimination edit
// stores version 2 with the edited rest lengths, and loading it back simulates with them.
// Oracles come from the catalogue and sim_core directly, not from the server.
#include "sim_core/app/catalog_link.h"

#include <gtest/gtest.h>
#include <stdlib.h>  // mkdtemp

#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "assets/avatar_import.h"
#include "bus/channels.h"
#include "bus/lcm_bus.h"
#include "bus/typed_bus.h"
#include "catalog/catalog_loader.h"
#include "catalog/import.h"
#include "sim_core/app/sim_server.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/common/input_error.h"
#include "tests/support/shared_data.h"
#include "tests/support/test_scenes.h"

namespace costume::sim_app {
namespace {

namespace fs = std::filesystem;
using costume_lcm::command;
using catalog::Kind;

/// CesiumMan (a glTF avatar with its own skeleton), from the shared data folder.
const fs::path kCesiumMan = ::costume::test::kSharedData / "khronos-cesiumman/CesiumMan.glb";

/// The built-in humanoid walking in a coarse skirt (pattern "skirt", as the default scene's
/// garment, so it maps onto the seeded entry "skirt").
sim::SceneDescription SkirtScene() {
  sim::SceneDescription scene;
  scene.name = "catalog_link_test";
  scene.solver.tolerance = 1e-2;
  sim::AvatarSpec avatar;
  avatar.avatar = sim::MakeHumanoid();
  avatar.clip = std::make_shared<sim::Clip>(
      sim::MakeBuiltInClip("walk", avatar.avatar->shared_skeleton()));
  scene.avatar = avatar;
  sim::Material cotton;
  cotton.name = "skirt_cotton";
  cotton.stretch_stiffness = cotton.shear_stiffness = 300.0;
  scene.materials.push_back(cotton);
  sim::GarmentSpec skirt;
  skirt.name = "skirt";
  skirt.material = "skirt_cotton";
  skirt.pattern = "skirt";
  skirt.pattern_resolution = 24;
  scene.garments.push_back(skirt);
  return scene;
}

class CatalogLinkTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/catalog-link-XXXXXX";
    ASSERT_NE(mkdtemp(pattern), nullptr);
    dir_ = pattern;
    url_ = "sqlite:" + dir_ + "/catalog.sqlite";
    catalog_ = catalog::Catalog::Open(url_);  // seeds; the server opens its own connection
    bus::Subscribe<costume_lcm::status>(bus_, bus::kSimStatusChannel,
                                        [this](const costume_lcm::status& m) {
                                          for (const auto& w : m.warnings) warnings_.push_back(w);
                                        });
  }
  void TearDown() override {
    server_.reset();
    catalog_.reset();
    fs::remove_all(dir_);
  }

  void Start(sim::SceneDescription scene, std::string url = "") {
    SimServerOptions options;
    options.catalog_url = url.empty() ? url_ : url;
    options.open_catalog = [u = options.catalog_url] { return OpenSceneCatalog(u); };
    server_ = std::make_unique<SimServer>(bus_, std::move(scene), options);
  }
  void Step(int n = 1) {
    for (int i = 0; i < n; ++i) {
      server_->Step();
      bus_.HandleSubscriptions(0);
    }
  }
  void Send(command c) {
    c.utime = bus::NowUtime();
    publisher_.Publish(c);
  }
  /// Sends SAVE_VERSION with `label` and runs the step that saves it.
  void SaveVersion(const std::string& label) {
    command save{};
    save.kind = command::KIND_SAVE_VERSION;
    save.name = label;
    Send(save);
    Step();
  }
  void SendLoad(std::int8_t kind, std::int64_t id, const std::string& name = "") {
    command c{};
    c.kind = kind;
    c.database_id = id;
    c.name = name;
    Send(c);
  }
  std::int64_t Id(Kind kind, const std::string& name) { return catalog_->Find(kind, name)->id; }
  /// Whether a warning since the last call contains `text` (the list is then cleared).
  bool Warned(const std::string& text) {
    bool found = false;
    for (const std::string& w : warnings_) found = found || w.find(text) != std::string::npos;
    warnings_.clear();
    return found;
  }
  /// Particles of the scene with garment `name` of the catalogue, built without the server.
  int ParticlesWith(const std::string& name) {
    sim::SceneDescription scene = SkirtScene();
    scene.garments.clear();
    catalog::AddGarmentToScene(*catalog_, Id(Kind::kGarment, name), 0, scene);
    return sim::Simulation::Build(scene)->model().num_particles();
  }
  int Particles() const { return server_->simulation().model().num_particles(); }
  std::vector<double> RestLengths(const sim::ClothModel& model) const {
    std::vector<double> lengths;
    for (const sim::Spring& s : model.springs()) lengths.push_back(s.rest_length);
    return lengths;
  }

  std::string dir_, url_;
  std::unique_ptr<catalog::Catalog> catalog_;
  bus::LcmBus bus_{"memq://"};
  bus::Publisher<command> publisher_{bus_, bus::kCommandChannel};
  std::vector<std::string> warnings_;
  std::unique_ptr<SimServer> server_;
};

TEST_F(CatalogLinkTest, LoadCostumeByNameAndByIdReplacesTheGarmentKeepingModeAndPlayback) {
  Start(SkirtScene());
  const int skirt = Particles();
  Send([] { command c{}; c.kind = command::KIND_SET_MODE; c.mode = command::MODE_EDITING; return c; }());
  Step(5);
  SendLoad(command::KIND_LOAD_COSTUME, 0, "cape");
  Step();
  ASSERT_EQ(server_->scene().garments.size(), 1u);
  EXPECT_EQ(server_->scene().garments[0].name, "cape");
  EXPECT_EQ(Particles(), ParticlesWith("cape"));
  EXPECT_NE(Particles(), skirt);
  EXPECT_EQ(server_->frame(), 1);  // rebuilt at frame 0, then one frame played
  EXPECT_EQ(server_->mode(), Mode::kEditing);
  EXPECT_EQ(server_->playback(), Playback::kPlaying);
  EXPECT_TRUE(server_->simulation().avatar_frozen());

  SendLoad(command::KIND_LOAD_COSTUME, Id(Kind::kGarment, "dress"));
  Step();
  EXPECT_EQ(server_->scene().garments[0].name, "dress");
  EXPECT_EQ(Particles(), ParticlesWith("dress"));
  EXPECT_EQ(server_->ignored().commands_refused, 0);
}

TEST_F(CatalogLinkTest, LoadAnimationByNameAndByIdReplacesTheClip) {
  Start(SkirtScene());
  const auto skeleton = server_->scene().avatar->avatar->shared_skeleton();
  const double walk = server_->scene().avatar->clip->duration();
  SendLoad(command::KIND_LOAD_ANIMATION, 0, "dance");
  Step(3);
  const double dance = sim::MakeBuiltInClip("dance", skeleton).duration();
  ASSERT_NE(dance, walk);
  EXPECT_EQ(server_->scene().avatar->clip->duration(), dance);
  EXPECT_EQ(server_->simulation().scene().avatar->clip->duration(), dance);
  EXPECT_EQ(server_->frame(), 3);

  SendLoad(command::KIND_LOAD_ANIMATION, Id(Kind::kAnimation, "walk"));
  Step();
  EXPECT_EQ(server_->simulation().scene().avatar->clip->duration(), walk);
  EXPECT_EQ(server_->simulation().scene().avatar->clip->name, "walk");
}

TEST_F(CatalogLinkTest, LoadAvatarByIdAndByNameRefitsThePatternGarment) {
  if (!fs::exists(kCesiumMan)) GTEST_SKIP() << kCesiumMan << " is absent";
  std::ifstream in(kCesiumMan, std::ios::binary);
  catalog::NewEntry entry;
  entry.kind = Kind::kAvatar;
  entry.name = "CesiumMan";
  entry.data = {"glb", std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), {})};
  const std::int64_t cesium = catalog_->Add(entry);
  const int cesium_joints = assets::LoadAvatar(kCesiumMan.string())->skeleton().num_joints();
  const int humanoid_joints = sim::MakeHumanoid()->skeleton().num_joints();
  ASSERT_NE(cesium_joints, humanoid_joints);

  Start(SkirtScene());
  SendLoad(command::KIND_LOAD_AVATAR, cesium);
  Step();
  ASSERT_NE(server_->simulation().avatar(), nullptr);
  EXPECT_EQ(server_->simulation().avatar()->avatar().skeleton().num_joints(), cesium_joints);
  EXPECT_EQ(server_->scene().garments[0].name, "skirt");  // kept, fitted to the new body
  EXPECT_EQ(server_->ignored().commands_refused, 0);

  SendLoad(command::KIND_LOAD_AVATAR, 0, "humanoid");
  Step();
  EXPECT_EQ(server_->simulation().avatar()->avatar().skeleton().num_joints(), humanoid_joints);
}

TEST_F(CatalogLinkTest, AClipThatSwingsTheForearmsThroughTheHipsIsSpreadAndSaysSo) {
  const fs::path bvh = ::costume::test::kSharedData / "cmu-mocap-bvh/02_02.bvh";
  if (!fs::exists(kCesiumMan) || !fs::exists(bvh)) GTEST_SKIP() << "needs CesiumMan and 02_02";
  const auto add = [this](Kind kind, const std::string& name, const std::string& format,
                          const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    catalog::NewEntry entry;
    entry.kind = kind;
    entry.name = name;
    entry.data = {format, std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), {})};
    if (kind == Kind::kAnimation) entry.category = "basic";
    return catalog_->Add(entry);
  };
  const std::int64_t cesium = add(Kind::kAvatar, "CesiumMan", "glb", kCesiumMan);
  const std::int64_t cmu = add(Kind::kAnimation, "CMU 02_02", "bvh", bvh);
  Start(SkirtScene());
  SendLoad(command::KIND_LOAD_AVATAR, cesium);
  Step();
  EXPECT_FALSE(Warned("arms spread"));  // the built-in walk keeps his forearms off his hips
  EXPECT_EQ(server_->simulation().arm_spread().angle[0], 0.0);
  SendLoad(command::KIND_LOAD_ANIMATION, cmu);
  Step();
  ASSERT_EQ(server_->ignored().commands_refused, 0);
  const sim::ArmSpreadFit& spread = server_->simulation().arm_spread();
  EXPECT_GT(spread.angle[0], 0.0);
  EXPECT_GT(spread.angle[1], 0.0);
  const auto names_both = [](const std::string& w) {
    return w.find("CMU 02_02") != std::string::npos && w.find("arms spread") != std::string::npos;
  };
  EXPECT_TRUE(std::any_of(warnings_.begin(), warnings_.end(), names_both))
      << "a warning names the entry and the spread";
}

TEST_F(CatalogLinkTest, RefusalsKeepTheOldSimulationAndNameTheEntry) {
  Start(SkirtScene());
  const int particles = Particles();
  Step(4);
  SendLoad(command::KIND_LOAD_COSTUME, 987654);
  Step();
  EXPECT_TRUE(Warned("987654"));
  SendLoad(command::KIND_LOAD_ANIMATION, 0, "nonesuch");
  Step();
  EXPECT_TRUE(Warned("'nonesuch'"));
  SendLoad(command::KIND_LOAD_COSTUME, Id(Kind::kAvatar, "humanoid"));  // wrong kind
  Step();
  EXPECT_TRUE(Warned("not a garment"));
  EXPECT_EQ(server_->ignored().commands_refused, 3);
  EXPECT_EQ(server_->frame(), 7);  // never rebuilt
  EXPECT_EQ(Particles(), particles);
  EXPECT_EQ(server_->scene().garments[0].name, "skirt");
}

TEST_F(CatalogLinkTest, AGarmentThatCannotBeFittedIsRefused) {
  sim::Material soft;
  soft.name = "soft";
  Start(test::HangScene(9, soft));  // no avatar: a built-in pattern cannot be fitted
  Step(2);
  SendLoad(command::KIND_LOAD_COSTUME, 0, "skirt");
  SendLoad(command::KIND_LOAD_ANIMATION, 0, "walk");
  Step();
  EXPECT_EQ(server_->ignored().commands_refused, 2);
  EXPECT_EQ(Particles(), 81);
  EXPECT_EQ(server_->frame(), 3);
  EXPECT_EQ(server_->scene().garments[0].name, "sheet");
  EXPECT_TRUE(Warned("garment 'skirt'"));
}

// A MakeHuman suit from the catalogue is worn by the MakeHuman body it was imported with and
// by no other avatar: loaded onto another avatar it brings its body (and says so); another
// avatar loaded under it is refused, keeping what runs.
TEST_F(CatalogLinkTest, AMakeHumanSuitIsWornByItsBodyOnly) {
  const fs::path data = ::costume::test::kSharedData;
  const std::string suit = "makehuman/clothes/female_casualsuit02/female_casualsuit02.mhclo";
  if (!fs::exists(data / suit)) GTEST_SKIP() << data / suit << " is absent";
  auto import = [&](Kind kind, std::vector<std::string> files) {
    catalog::ImportRequest request;
    request.kind = kind;
    request.root = data.string();
    for (std::string& file : files) request.files.push_back((data / file).string());
    std::ostringstream progress;
    return catalog::ImportFiles(*catalog_, request, progress).at(0);
  };
  const std::int64_t body = import(Kind::kAvatar, {"makehuman/body/base.obj",
                                                   "makehuman/body/default.mhskel",
                                                   "makehuman/body/default_weights.mhw"});
  const std::int64_t suit_id = import(Kind::kGarment, {suit});
  const int body_vertices = catalog::LoadAvatar(*catalog_, body)->num_vertices();

  Start(SkirtScene());
  SendLoad(command::KIND_LOAD_COSTUME, suit_id);
  Step();
  EXPECT_TRUE(Warned("on the body it is made for: the avatar is now 'MakeHuman's base.obj'"));
  EXPECT_EQ(server_->scene().garments[0].name, "female_casualsuit02");
  EXPECT_EQ(server_->simulation().avatar()->avatar().num_vertices(), body_vertices);
  EXPECT_EQ(server_->ignored().commands_refused, 0);

  SendLoad(command::KIND_LOAD_AVATAR, 0, "humanoid");
  Step();
  EXPECT_TRUE(Warned("the avatar 'built-in humanoid' has another skin"));
  EXPECT_EQ(server_->ignored().commands_refused, 1);
  EXPECT_EQ(server_->simulation().avatar()->avatar().num_vertices(), body_vertices);

  // The catalogue's own MakeHuman avatar is that body: loading it changes nothing it wears.
  SendLoad(command::KIND_LOAD_AVATAR, body);
  Step();
  EXPECT_EQ(server_->ignored().commands_refused, 1);
  EXPECT_EQ(server_->scene().garments[0].name, "female_casualsuit02");

  // A saved edit (its model alone) is the same body's: it brings that body, is refused on
  // another avatar, and its thumbnail is drawn on that body.
  SaveVersion("as worn");
  ASSERT_TRUE(Warned("version 2"));
  const sim::GarmentSpec saved = catalog::LoadGarment(*catalog_, suit_id, 2);
  ASSERT_NE(saved.model, nullptr);
  ASSERT_NE(saved.made_for, nullptr);
  EXPECT_TRUE(sim::SameRestSkin(*saved.made_for, *catalog::LoadAvatar(*catalog_, body)));
  sim::SceneDescription other = SkirtScene();
  other.garments.clear();
  EXPECT_TRUE(catalog::AddGarmentToScene(*catalog_, suit_id, 2, other));
  other.avatar->avatar = sim::MakeHumanoid();
  EXPECT_THROW(sim::ValidateScene(other), sim::InputError);
  int drawn_on = 0;
  std::ostringstream log;
  catalog_->FillMissingThumbnails(
      [&](const catalog::ThumbnailRequest& request) {
        if (request.name == "female_casualsuit02") drawn_on = request.avatar->num_vertices();
        return std::vector<std::uint8_t>{1};
      },
      64, log);
  EXPECT_EQ(drawn_on, saved.made_for->num_vertices()) << log.str();
}

TEST_F(CatalogLinkTest, ACatalogueThatCannotBeOpenedIsAWarningNamingItsUrl) {
  Start(SkirtScene(), "postgresql://127.0.0.1:1/none?connect_timeout=2");
  SendLoad(command::KIND_LOAD_COSTUME, 0, "cape");
  Step();
  EXPECT_TRUE(Warned("postgresql://127.0.0.1:1/none"));
  EXPECT_EQ(server_->scene().garments[0].name, "skirt");
  EXPECT_EQ(server_->frame(), 1);
}

TEST_F(CatalogLinkTest, SetMaterialChangesTheFabricOfTheRunningGarment) {
  Start(SkirtScene());
  const double k_before = server_->simulation().model().springs()[0].stiffness;
  command c{};
  c.kind = command::KIND_SET_MATERIAL;
  c.garment = -1;
  c.material.density = 0.2;
  c.material.stretch_stiffness = c.material.shear_stiffness = 600.0;
  c.material.bending_rigidity = 1e-5;
  c.material.damping = 1e-3;
  c.material.air_drag = 0.02;
  c.material.friction = 0.3;
  Send(c);
  Step();
  EXPECT_EQ(server_->ignored().commands_refused, 0);
  EXPECT_EQ(server_->scene().garments[0].material, "skirt_fabric");
  const double k_after = server_->simulation().model().springs()[0].stiffness;
  EXPECT_NEAR(k_after / k_before, 2.0, 1e-9);  // spring stiffness is linear in the sheet's

  c.material.density = -1.0;  // refused: fabric unchanged
  Send(c);
  Step();
  EXPECT_EQ(server_->ignored().commands_refused, 1);
  EXPECT_EQ(server_->simulation().model().springs()[0].stiffness, k_after);
}

TEST_F(CatalogLinkTest, SaveVersionStoresTheEditedRestLengthsAndLoadsBack) {
  Start(SkirtScene());
  Send([] { command c{}; c.kind = command::KIND_SET_MODE; c.mode = command::MODE_EDITING; return c; }());
  Step(40);  // the skirt sags under gravity: its springs are longer than at rest
  const std::vector<double> built = RestLengths(server_->simulation().model());
  // A sphere around the whole hem: every spring in it takes its current length.
  Eigen::Vector3d low = server_->simulation().state().positions.row(0).transpose();
  for (int p = 0; p < Particles(); ++p) {
    if (server_->simulation().state().positions(p, 1) < low.y()) {
      low = server_->simulation().state().positions.row(p).transpose();
    }
  }
  command edit{};
  edit.kind = command::KIND_ELIMINATE_STRETCH;
  edit.grab_id = -1;
  for (int i = 0; i < 3; ++i) edit.centre[i] = low[i];
  edit.radius = 0.3;
  Send(edit);
  Step();
  const std::vector<double> edited = RestLengths(server_->simulation().model());
  ASSERT_NE(edited, built);

  SaveVersion("hem relaxed");
  EXPECT_TRUE(Warned("version 2"));
  const std::int64_t skirt = Id(Kind::kGarment, "skirt");
  const auto versions = catalog_->Versions(skirt);
  ASSERT_EQ(versions.size(), 2u);
  EXPECT_EQ(versions[1].label, "hem relaxed");
  const sim::GarmentSpec saved = catalog::LoadGarment(*catalog_, skirt, 2);
  ASSERT_NE(saved.model, nullptr);
  EXPECT_EQ(RestLengths(*saved.model), edited);

  // Back into a fresh scene: the server simulates the saved rest lengths.
  SendLoad(command::KIND_LOAD_COSTUME, 0, "cape");
  Step();
  ASSERT_EQ(server_->scene().garments[0].name, "cape");
  SendLoad(command::KIND_LOAD_COSTUME, skirt);
  Step();
  EXPECT_EQ(server_->ignored().commands_refused, 0);
  EXPECT_EQ(RestLengths(server_->simulation().model()), edited);
}

}  // namespace
}  // namespace costume::sim_app
