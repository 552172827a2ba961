// The edited-garment format: a garment written and read back simulates exactly as before
// (every double bit for bit), edited rest lengths survive, and damaged bytes are refused.

#include "assets/edited_garment.h"

#include <gtest/gtest.h>

#include <cstring>

#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/common/input_error.h"
#include "sim_core/scene/simulation.h"
#include "tests/support/test_scenes.h"

namespace costume::assets {
namespace {

using sim::SceneDescription;
using sim::Simulation;

/// The built-in skirt (coarse, for speed) on the walking humanoid.
SceneDescription SkirtScene() {
  static const auto humanoid = sim::MakeHumanoid();
  SceneDescription scene;
  scene.source = "edited_garment_test";
  sim::AvatarSpec avatar;
  avatar.avatar = humanoid;
  avatar.clip =
      std::make_shared<const sim::Clip>(sim::MakeBuiltInClip("walk", humanoid->shared_skeleton()));
  avatar.motion.fit_time = 0.1;
  scene.avatar = avatar;
  sim::GarmentSpec skirt;
  skirt.name = "skirt";
  skirt.pattern = "skirt";
  skirt.pattern_resolution = 24;
  scene.garments.push_back(skirt);
  return scene;
}

/// `scene` with its one garment replaced by the prebuilt `garment`.
SceneDescription WithPrebuilt(SceneDescription scene, const EditedGarment& garment) {
  sim::GarmentSpec& spec = scene.garments.at(0);
  spec.pattern.reset();
  spec.panel.reset();
  spec.model = garment.model;
  spec.attach_to = garment.attached_to;
  return scene;
}

std::vector<double> RestLengths(const sim::ClothModel& model) {
  std::vector<double> lengths;
  for (const sim::Spring& s : model.springs()) lengths.push_back(s.rest_length);
  return lengths;
}

TEST(EditedGarment, ARoundTrippedGarmentSimulatesIdentically) {
  const SceneDescription scene = SkirtScene();
  auto original = Simulation::Build(scene);
  const std::vector<std::uint8_t> bytes =
      WriteEditedGarment(EditedGarmentFromSimulation(*original, "skirt"));
  const EditedGarment read = ReadEditedGarment(bytes, "skirt.cdgarment");
  ASSERT_TRUE(read.attached_to);
  EXPECT_EQ(*read.attached_to, sim::HAnimJoint::kSacroiliac);  // the skirt's waistband
  auto copy = Simulation::Build(WithPrebuilt(scene, read));
  ASSERT_EQ(copy->model().num_particles(), original->model().num_particles());
  ASSERT_EQ(copy->attachments().size(), original->attachments().size());
  for (int frame = 0; frame < 30; ++frame) {
    original->AdvanceFrame();
    copy->AdvanceFrame();
  }
  // Bit for bit: the same model, attachments and steps give the same floating-point result.
  EXPECT_TRUE(copy->state().positions == original->state().positions);
  EXPECT_TRUE(copy->state().velocities == original->state().velocities);
  // And the cloth did move, so the comparison means something.
  EXPECT_GT((original->state().positions - original->model().rest_positions()).norm(), 1e-3);
}

TEST(EditedGarment, EditedRestLengthsAreKept) {
  auto sheet = Simulation::Build(test::HangScene(9));
  for (int frame = 0; frame < 30; ++frame) sheet->AdvanceFrame();  // sags and stretches
  const std::vector<double> before = RestLengths(sheet->model());
  ASSERT_GT(sheet->EliminateStretchEnergy(Eigen::Vector3d(0, -0.5, -0.5), 2.0), 0);
  const std::vector<double> edited = RestLengths(sheet->model());
  ASSERT_NE(edited, before);
  const EditedGarment read = ReadEditedGarment(
      WriteEditedGarment(EditedGarmentFromSimulation(*sheet, "sheet")), "sheet.cdgarment");
  EXPECT_EQ(RestLengths(*read.model), edited);
  EXPECT_FALSE(read.attached_to);
  EXPECT_EQ(read.model->pinned(), sheet->model().pinned());
  EXPECT_EQ(read.model->lattice_cols(), 9);  // a single garment keeps its lattice shape
  // Built into a new scene, the model keeps them.
  auto reloaded = Simulation::Build(WithPrebuilt(test::HangScene(9), read));
  EXPECT_EQ(RestLengths(reloaded->model()), edited);
}

// From a scene of two garments, the second comes out with its own indices: the same model
// as when it is built alone.
TEST(EditedGarment, IsTakenOutOfAMergedModel) {
  SceneDescription two = test::HangScene(5);
  sim::GarmentSpec second = two.garments[0];
  second.name = "second";
  second.panel->cols = second.panel->rows = 7;
  second.panel->origin.z() = 1.0;
  for (Eigen::Vector3d& pin : second.pin_points) pin.z() += 1.5;
  two.garments.push_back(second);
  auto merged = Simulation::Build(two);
  const EditedGarment taken = EditedGarmentFromSimulation(*merged, "second");

  SceneDescription alone = test::HangScene(7);
  alone.garments[0] = second;
  auto single = Simulation::Build(alone);
  const sim::ClothModel& expected = single->model();
  ASSERT_EQ(taken.model->num_particles(), expected.num_particles());
  EXPECT_TRUE(taken.model->rest_positions() == expected.rest_positions());
  EXPECT_TRUE(taken.model->masses() == expected.masses());
  EXPECT_EQ(taken.model->pinned(), expected.pinned());
  ASSERT_EQ(taken.model->num_springs(), expected.num_springs());
  for (int s = 0; s < expected.num_springs(); ++s) {
    EXPECT_EQ(taken.model->springs()[s].a, expected.springs()[s].a);
    EXPECT_EQ(taken.model->springs()[s].b, expected.springs()[s].b);
    EXPECT_EQ(taken.model->springs()[s].rest_length, expected.springs()[s].rest_length);
  }
  EXPECT_EQ(taken.model->triangles(), expected.triangles());
  EXPECT_EQ(taken.model->lattice_cols(), 0);  // the merged model has no lattice shape
}

TEST(EditedGarment, TakesItsMaterialFromTheScene) {
  sim::Material silk;
  silk.name = "silk";
  silk.density = 0.06;
  silk.friction = 0.25;
  auto sheet = Simulation::Build(test::HangScene(5, silk));
  const EditedGarment garment = EditedGarmentFromSimulation(*sheet, "sheet");
  EXPECT_EQ(garment.material.name, "silk");
  EXPECT_EQ(garment.material.friction, 0.25);
  const EditedGarment read = ReadEditedGarment(WriteEditedGarment(garment), "x");
  EXPECT_EQ(read.material.density, 0.06);
  EXPECT_THROW(EditedGarmentFromSimulation(*sheet, "cape"), sim::InputError);
}

TEST(EditedGarment, APrebuiltModelIsOneOfTheGarmentShapes) {
  auto sheet = Simulation::Build(test::HangScene(5));
  SceneDescription both = test::HangScene(5);
  both.garments[0].model = sheet->shared_model();  // and the panel is still set
  try {
    sim::ValidateScene(both);
    FAIL() << "no throw";
  } catch (const sim::InputError& error) {
    EXPECT_NE(std::string(error.what()).find("prebuilt model"), std::string::npos) << error.what();
  }
  both.garments[0].panel.reset();
  EXPECT_NO_THROW(sim::ValidateScene(both));
}

/// The message ReadEditedGarment throws for `bytes` (empty when it accepts them).
std::string Refusal(const std::vector<std::uint8_t>& bytes) {
  try {
    ReadEditedGarment(bytes, "damaged.cdgarment");
  } catch (const sim::InputError& error) {
    return error.what();
  }
  return "";
}

TEST(EditedGarment, RefusesDamagedBytes) {
  auto sheet = Simulation::Build(test::HangScene(5));
  const std::vector<std::uint8_t> good =
      WriteEditedGarment(EditedGarmentFromSimulation(*sheet, "sheet"));
  ASSERT_EQ(Refusal(good), "");

  std::vector<std::uint8_t> magic = good;
  magic[0] = 'X';
  EXPECT_NE(Refusal(magic).find("CDGARMNT"), std::string::npos) << Refusal(magic);

  std::vector<std::uint8_t> newer = good;
  newer[8] = 2;
  EXPECT_NE(Refusal(newer).find("version 2"), std::string::npos) << Refusal(newer);

  for (std::size_t cut : {std::size_t{3}, std::size_t{20}, good.size() / 2, good.size() - 1}) {
    const std::string message =
        Refusal(std::vector<std::uint8_t>(good.begin(), good.begin() + cut));
    EXPECT_NE(message.find("damaged.cdgarment"), std::string::npos) << cut << ": " << message;
  }
  std::vector<std::uint8_t> longer = good;
  longer.push_back(0);
  EXPECT_NE(Refusal(longer).find("unexpected bytes"), std::string::npos);

  // A spring index out of range: the model's own validation speaks.
  std::uint32_t header_size;
  std::memcpy(&header_size, good.data() + 12, 4);
  const std::size_t n = sheet->model().num_particles();
  const std::size_t first_spring = 16 + header_size + 8 * (3 * n + 3 * n);  // has drag
  std::vector<std::uint8_t> bad_index = good;
  const std::int32_t far = 1 << 20;
  std::memcpy(bad_index.data() + first_spring, &far, 4);
  EXPECT_NE(Refusal(bad_index).find("damaged.cdgarment"), std::string::npos) << Refusal(bad_index);
}

}  // namespace
}  // namespace costume::assets
