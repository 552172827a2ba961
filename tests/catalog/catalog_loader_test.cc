// Catalogue entries turned into simulation inputs: the built-ins match what sim_core makes
// directly, and a garment saved after a stretch-energy edit comes back with its rest lengths.

#include "catalog/catalog_loader.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <sstream>
#include <utility>
#include <vector>

#include "assets/edited_garment.h"
#include "catalog/fabric_presets.h"
#include "sim_core/avatar/clip.h"
#include "sim_core/avatar/pose.h"
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
    const auto clip = LoadClip(*catalog_, Id(Kind::kAnimation, name));
    const sim::Clip made = sim::MakeBuiltInClip(name, humanoid->shared_skeleton());
    EXPECT_EQ(clip->frames.size(), made.frames.size()) << name;
    EXPECT_EQ(clip->frame_time, made.frame_time) << name;
    EXPECT_EQ(clip->category,
              name == "dance" ? sim::ClipCategory::kChoreography : sim::ClipCategory::kBasic);
  }
}

/// The built-in humanoid's skeleton with its arms raised `degrees` about the shoulders (both
/// outwards, about the forward axis): the rest of an imported avatar modelled in a T-pose.
std::shared_ptr<const sim::Skeleton> ArmsRaised(double degrees) {
  const auto humanoid = sim::MakeHumanoidSkeleton();
  std::vector<sim::Joint> joints;
  for (int j = 0; j < humanoid->num_joints(); ++j) joints.push_back(humanoid->joint(j));
  for (sim::HAnimJoint shoulder : {sim::HAnimJoint::kLShoulder, sim::HAnimJoint::kRShoulder}) {
    const int s = humanoid->Find(shoulder);
    const Eigen::Isometry3d& world = humanoid->rest_world()[s];
    const Eigen::Isometry3d& parent = humanoid->rest_world()[joints[s].parent];
    const Eigen::Vector3d elbow =
        humanoid->rest_world()[humanoid->Find(shoulder == sim::HAnimJoint::kLShoulder
                                                  ? sim::HAnimJoint::kLElbow
                                                  : sim::HAnimJoint::kRElbow)]
            .translation();
    // Outwards and up: about the axis that turns the hanging upper arm towards the side.
    const Eigen::Vector3d down = (elbow - world.translation()).normalized();
    const Eigen::Vector3d side(world.translation().x() > 0.0 ? 1.0 : -1.0, 0.0, 0.0);
    const Eigen::Vector3d axis = down.cross(side).normalized();
    Eigen::Isometry3d raised = world;
    raised.linear() = Eigen::AngleAxisd(degrees * M_PI / 180.0, axis) * world.linear();
    joints[s].rest_local = parent.inverse() * raised;
  }
  return sim::Skeleton::Create("arms raised", joints);
}

TEST_F(CatalogLoaderTest, ABuiltInClipSwingsTheArmsOfAnAvatarRestingInATPoseDownAsOnTheHumanoid) {
  // The walk's arms hang by the body whatever the avatar's rest: retargeted from the
  // skeleton its angles are written for, the elbows stay well below the shoulders. (Made
  // on the T-pose skeleton itself, the angles kept the arms near the horizontal.)
  const auto t_pose = ArmsRaised(80.0);
  const auto clip = LoadClip(*catalog_, Id(Kind::kAnimation, "walk"));
  const sim::Retargeter retargeter(clip->skeleton, t_pose);
  std::vector<Eigen::Isometry3d> world;
  sim::ComputeJointWorld(*t_pose, sim::RestPose(*t_pose), world);
  const int l_shoulder = t_pose->Find(sim::HAnimJoint::kLShoulder);
  const int l_elbow = t_pose->Find(sim::HAnimJoint::kLElbow);
  ASSERT_GT(world[l_elbow].translation().y(), world[l_shoulder].translation().y() - 0.1)
      << "the test skeleton's arm should rest near the horizontal";
  sim::Pose sampled, pose;
  for (double t : {0.0, 0.3, 0.6, 0.9}) {
    sim::SampleClip(*clip, t, sampled);
    retargeter.Apply(sampled, pose);
    sim::ComputeJointWorld(*t_pose, pose, world);
    for (auto [shoulder, elbow] : {std::pair{sim::HAnimJoint::kLShoulder, sim::HAnimJoint::kLElbow},
                                   std::pair{sim::HAnimJoint::kRShoulder, sim::HAnimJoint::kRElbow}}) {
      const Eigen::Vector3d upper_arm =
          world[t_pose->Find(shoulder)].translation() - world[t_pose->Find(elbow)].translation();
      // Hanging within 45° of the vertical: the elbow more than cos 45° of the upper arm's
      // length below the shoulder.
      EXPECT_GT(upper_arm.y(), std::cos(M_PI / 4) * upper_arm.norm())
          << "t = " << t << " s, " << sim::HAnimName(shoulder);
    }
  }
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

// `costume-catalog check` finds entries an import would refuse now (stored by older builds,
// or written by other programs): each named with its problem, the sound ones passed.
TEST_F(CatalogLoaderTest, CheckEntriesNamesEveryEntryThatWouldNotLoad) {
  NewEntry noise;
  noise.kind = Kind::kAvatar;
  noise.name = "noise";
  noise.data = {"glb", {'g', 'l', 'T', 'F', 0, 1, 2, 3}};
  catalog_->Add(noise);
  const std::int64_t skirt = Id(Kind::kGarment, "skirt");
  catalog_->SaveGarmentVersion(skirt, {"edited-garment", {'C', 'D', 'G'}}, "torn", {});
  std::ostringstream log;
  const std::vector<std::string> problems = CheckEntries(*catalog_, log);
  ASSERT_EQ(problems.size(), 2u) << log.str();
  EXPECT_NE(problems[0].find("catalog avatar 'noise'"), std::string::npos) << problems[0];
  EXPECT_NE(problems[1].find("catalog garment 'skirt' version 2"), std::string::npos)
      << problems[1];
  EXPECT_NE(log.str().find("catalog garment 'skirt' version 1 (id " + std::to_string(skirt) +
                           "): ok"),
            std::string::npos)
      << log.str();
  EXPECT_NE(log.str().find("catalog animation 'dance' (id "), std::string::npos) << log.str();
  // Progress first, the refusal (which names the entry again) on its own line.
  const std::string noise_id = std::to_string(Id(Kind::kAvatar, "noise"));
  EXPECT_NE(log.str().find("catalog avatar 'noise' (id " + noise_id +
                           "): refused\n  catalog avatar 'noise'"),
            std::string::npos)
      << log.str();
}

// A stored glTF whose skin has neither joints nor inverse bind matrices: assimp 5.2 crashes
// (SIGSEGV) reading it. A skin without matrices but with joints, which glTF allows, crashed
// it too before the importers wrote the matrices out; found as one flipped byte of a stored
// CesiumMan.glb, `costume-catalog check` died, and so would the simulation server loading the
// entry.
constexpr char kSkinWithoutJoints[] =
    R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0,1]}],"nodes":[{"name":"Hips"},)"
    R"({"name":"mesh","mesh":0,"skin":0}],"skins":[{"joints":[]}],"meshes":[{"primitives":[)"
    R"({"attributes":{"POSITION":0}}]}],"buffers":[{"byteLength":36,"uri":"data:application/)"
    R"(octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],"bufferViews":[)"
    R"({"buffer":0,"byteLength":36}],"accessors":[{"bufferView":0,"componentType":5126,)"
    R"("count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}]})";

TEST_F(CatalogLoaderTest, AStoredFileAnImporterCrashesOnIsReportedNotFatal) {
  NewEntry crasher;
  crasher.kind = Kind::kAvatar;
  crasher.name = "crasher";
  const std::string text = kSkinWithoutJoints;
  crasher.data = {"gltf", std::vector<std::uint8_t>(text.begin(), text.end())};
  const std::int64_t id = catalog_->Add(crasher);
  std::ostringstream log;
  const std::vector<std::string> problems = CheckEntries(*catalog_, log);
  ASSERT_EQ(problems.size(), 1u) << log.str();
  // "crashed (signal 11, SIGSEGV)"; under AddressSanitizer "ended without a result".
  EXPECT_NE(problems[0].find("catalog avatar 'crasher' (id " + std::to_string(id) +
                             "): reading it "),
            std::string::npos)
      << problems[0];
  EXPECT_NE(problems[0].find("the stored data is likely damaged"), std::string::npos);
  // Loaded here, as the simulation server loads an entry: assimp runs in a child first.
  try {
    LoadAvatar(*catalog_, id);
    ADD_FAILURE() << "no error";
  } catch (const sim::InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("the file is damaged or uses what this assimp cannot read"),
              std::string::npos)
        << message;
  }
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
