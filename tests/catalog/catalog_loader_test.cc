// Catalogue entries turned into simulation inputs: the built-ins match what sim_core makes
// directly, and a garment saved after a stretch-energy edit comes back with its rest lengths.

#include "catalog/catalog_loader.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "assets/edited_garment.h"
#include "catalog/fabric_presets.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/simulation.h"

namespace costume::catalog {
namespace {

class CatalogLoaderTest : public testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/catalog-loader-XXXXXX";
    ASSERT_NE(mkdtemp(pattern), nullptr);
    dir_ = pattern;
    catalog_ = Catalog::Open("sqlite:" + dir_ + "/catalog.sqlite");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::int64_t Id(Kind kind, const std::string& name) { return catalog_->Find(kind, name)->id; }

  std::string dir_;
  std::unique_ptr<Catalog> catalog_;
};

TEST_F(CatalogLoaderTest, BuiltInsLoadAsSimCoreMakesThem) {
  const auto humanoid = LoadAvatar(*catalog_, Id(Kind::kAvatar, "humanoid"));
  const auto direct = sim::MakeHumanoid();
  EXPECT_EQ(humanoid->num_vertices(), direct->num_vertices());
  EXPECT_TRUE(humanoid->rest_vertices() == direct->rest_vertices());

  for (const std::string& name : sim::BuiltInClipNames()) {
    const auto clip = LoadClip(*catalog_, Id(Kind::kAnimation, name), humanoid->shared_skeleton());
    const sim::Clip made = sim::MakeBuiltInClip(name, humanoid->shared_skeleton());
    EXPECT_EQ(clip->frames.size(), made.frames.size()) << name;
    EXPECT_EQ(clip->frame_time, made.frame_time) << name;
    EXPECT_EQ(clip->category,
              name == "dance" ? sim::ClipCategory::kChoreography : sim::ClipCategory::kBasic);
  }
  // Without a skeleton: the built-in humanoid's.
  EXPECT_EQ(LoadClip(*catalog_, Id(Kind::kAnimation, "walk"), nullptr)->skeleton->num_joints(),
            humanoid->skeleton().num_joints());
}

TEST_F(CatalogLoaderTest, ABuiltInGarmentDressesTheAvatarWithItsFabric) {
  const std::int64_t cape = Id(Kind::kGarment, "cape");
  catalog_->SetFabric(cape, FindFabricPreset("wool").fabric);
  sim::SceneDescription scene;
  scene.source = "catalog_loader_test";
  sim::AvatarSpec avatar;
  avatar.avatar = LoadAvatar(*catalog_, Id(Kind::kAvatar, "humanoid"));
  scene.avatar = avatar;
  AddGarmentToScene(*catalog_, cape, 0, scene);
  ASSERT_EQ(scene.garments.size(), 1u);
  EXPECT_EQ(*scene.garments[0].pattern, "cape");
  EXPECT_EQ(scene.garments[0].name, "cape");
  ASSERT_EQ(scene.materials.size(), 1u);
  EXPECT_EQ(scene.materials[0].name, scene.garments[0].material);
  EXPECT_EQ(scene.materials[0].density, FindFabricPreset("wool").fabric.mass_per_area);
  auto simulation = sim::Simulation::Build(scene);
  // The cloth's mass is its area times the wool's mass per area: about 0.25 kg/m² × a
  // cape's square metre or so, certainly between 0.05 and 1 kg.
  EXPECT_GT(simulation->model().total_mass(), 0.05);
  EXPECT_LT(simulation->model().total_mass(), 1.0);
  AddGarmentToScene(*catalog_, cape, 0, scene);  // the material is replaced, not repeated
  EXPECT_EQ(scene.materials.size(), 1u);
}

TEST_F(CatalogLoaderTest, AnEditedGarmentVersionKeepsItsRestLengths) {
  const std::int64_t skirt = Id(Kind::kGarment, "skirt");
  sim::SceneDescription scene;
  scene.source = "catalog_loader_test";
  sim::AvatarSpec avatar;
  avatar.avatar = LoadAvatar(*catalog_, Id(Kind::kAvatar, "humanoid"));
  scene.avatar = avatar;
  AddGarmentToScene(*catalog_, skirt, 0, scene);
  scene.garments[0].pattern_resolution = 24;
  auto simulation = sim::Simulation::Build(scene);
  for (int frame = 0; frame < 20; ++frame) simulation->AdvanceFrame();
  const Eigen::Vector3d hem = simulation->state().positions.row(0).transpose();
  ASSERT_GT(simulation->EliminateStretchEnergy(hem, 0.3), 0);
  std::vector<double> edited;
  for (const sim::Spring& s : simulation->model().springs()) edited.push_back(s.rest_length);

  const auto bytes =
      assets::WriteEditedGarment(assets::EditedGarmentFromSimulation(*simulation, "skirt"));
  const int version =
      catalog_->SaveGarmentVersion(skirt, {"edited-garment", bytes}, "hem eased", {});
  EXPECT_EQ(version, 2);
  const sim::GarmentSpec saved = LoadGarment(*catalog_, skirt, 2);
  ASSERT_TRUE(saved.model);
  std::vector<double> loaded;
  for (const sim::Spring& s : saved.model->springs()) loaded.push_back(s.rest_length);
  EXPECT_EQ(loaded, edited);
  EXPECT_EQ(*saved.attach_to, sim::HAnimJoint::kSacroiliac);
  // The first version is still the pattern.
  EXPECT_EQ(*LoadGarment(*catalog_, skirt, 1).pattern, "skirt");
  // The latest builds into a simulation with the edited lengths.
  sim::SceneDescription again = scene;
  again.garments.clear();
  AddGarmentToScene(*catalog_, skirt, 0, again);
  auto reloaded = sim::Simulation::Build(again);
  std::vector<double> rebuilt;
  for (const sim::Spring& s : reloaded->model().springs()) rebuilt.push_back(s.rest_length);
  EXPECT_EQ(rebuilt, edited);
}

TEST_F(CatalogLoaderTest, AnEntryOfAnotherKindIsRefusedByName) {
  try {
    LoadAvatar(*catalog_, Id(Kind::kAnimation, "kick"));
    FAIL() << "no throw";
  } catch (const sim::InputError& error) {
    EXPECT_NE(std::string(error.what()).find("'kick'"), std::string::npos) << error.what();
  }
  EXPECT_THROW(LoadGarment(*catalog_, Id(Kind::kGarment, "dress"), 7), sim::InputError);
}

}  // namespace
}  // namespace costume::catalog
