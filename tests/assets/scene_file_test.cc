#include "assets/scene_file.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/common/input_error.h"
#include "tests/support/shared_data.h"

namespace costume::assets {
namespace {

using sim::InputError;
using sim::SceneDescription;

/// A valid scene with one garment; the tests append or replace parts of it.
constexpr const char* kMinimalScene = R"toml(
[[garment]]
name = "sheet"
[garment.panel]
)toml";

/// Passes when `text` contains `part`; on failure shows both.
::testing::AssertionResult Contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "\"" << text << "\"\n  does not contain\n\"" << part << "\"";
}

/// 1-based line of the first occurrence of `needle` in `text` (0 when absent).
int LineOf(const std::string& text, const std::string& needle) {
  const std::size_t at = text.find(needle);
  if (at == std::string::npos) return 0;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
}

/// "test.toml:<line>:" for the line holding `needle`.
std::string LocationOf(const std::string& text, const std::string& needle) {
  return "test.toml:" + std::to_string(LineOf(text, needle)) + ":";
}

/// The message ParseSceneText throws for `text` ("" and a test failure when it accepts it).
std::string ErrorOf(const std::string& text, const std::string& base_dir = "") {
  try {
    ParseSceneText(text, "test.toml", base_dir);
  } catch (const InputError& error) {
    return error.what();
  }
  ADD_FAILURE() << "accepted:\n" << text;
  return "";
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void ExpectSameScene(const SceneDescription& a, const SceneDescription& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.duration, b.duration);
  EXPECT_EQ(a.frame_rate, b.frame_rate);
  EXPECT_EQ(a.gravity, b.gravity);
  EXPECT_EQ(a.solver.method, b.solver.method);
  EXPECT_EQ(a.solver.tolerance, b.solver.tolerance);
  EXPECT_EQ(a.solver.max_iterations, b.solver.max_iterations);
  EXPECT_EQ(a.solver.substeps, b.solver.substeps);
  EXPECT_EQ(a.effects.air_drag, b.effects.air_drag);
  EXPECT_EQ(a.effects.friction, b.effects.friction);
  EXPECT_EQ(a.effects.self_collision, b.effects.self_collision);
  ASSERT_EQ(a.materials.size(), b.materials.size());
  ASSERT_EQ(a.garments.size(), b.garments.size());
  for (std::size_t i = 0; i < a.garments.size(); ++i) {
    const sim::GarmentSpec& ga = a.garments[i];
    const sim::GarmentSpec& gb = b.garments[i];
    EXPECT_EQ(ga.name, gb.name);
    EXPECT_EQ(ga.material, gb.material);
    EXPECT_EQ(ga.pin_points, gb.pin_points);
    EXPECT_EQ(ga.pin_tolerance, gb.pin_tolerance);
    EXPECT_EQ(ga.source_line, gb.source_line);
    ASSERT_EQ(ga.panel.has_value(), gb.panel.has_value());
    if (ga.panel) {
      EXPECT_EQ(ga.panel->origin, gb.panel->origin);
      EXPECT_EQ(ga.panel->u_axis, gb.panel->u_axis);
      EXPECT_EQ(ga.panel->v_axis, gb.panel->v_axis);
      EXPECT_EQ(ga.panel->width, gb.panel->width);
      EXPECT_EQ(ga.panel->height, gb.panel->height);
      EXPECT_EQ(ga.panel->cols, gb.panel->cols);
      EXPECT_EQ(ga.panel->rows, gb.panel->rows);
    }
  }
  ASSERT_EQ(a.spheres.size(), b.spheres.size());
  for (std::size_t i = 0; i < a.spheres.size(); ++i) {
    EXPECT_EQ(a.spheres[i].center, b.spheres[i].center);
    EXPECT_EQ(a.spheres[i].radius, b.spheres[i].radius);
    EXPECT_EQ(a.spheres[i].thickness, b.spheres[i].thickness);
    EXPECT_EQ(a.spheres[i].friction, b.spheres[i].friction);
  }
}

// ---- built-in scenes --------------------------------------------------------------------

TEST(BuiltInScenes, HangIsOne33By33SheetPinnedAtTwoCorners) {
  const SceneDescription scene = LoadBuiltInScene("hang");
  EXPECT_EQ(scene.name, "hang");
  EXPECT_EQ(scene.duration, 2.0);
  EXPECT_EQ(scene.frame_rate, 60.0);
  EXPECT_EQ(scene.gravity, Eigen::Vector3d(0.0, -9.81, 0.0));
  EXPECT_EQ(scene.solver.method, sim::SolverMethod::kPcg);
  EXPECT_TRUE(scene.spheres.empty());
  ASSERT_EQ(scene.garments.size(), 1u);
  const sim::GarmentSpec& sheet = scene.garments[0];
  EXPECT_EQ(sheet.material, "stiff_cotton");
  ASSERT_TRUE(sheet.panel.has_value());
  EXPECT_FALSE(sheet.mesh.has_value());
  EXPECT_EQ(sheet.panel->cols, 33);
  EXPECT_EQ(sheet.panel->rows, 33);
  EXPECT_EQ(sheet.panel->width, 1.0);
  EXPECT_EQ(sheet.panel->height, 1.0);
  EXPECT_EQ(sheet.panel->origin, Eigen::Vector3d(-0.5, 0.0, -0.5));
  ASSERT_EQ(sheet.pin_points.size(), 2u);
  EXPECT_EQ(sheet.pin_points[0], Eigen::Vector3d(-0.5, 0.0, -0.5));
  EXPECT_EQ(sheet.pin_points[1], Eigen::Vector3d(0.5, 0.0, -0.5));
  EXPECT_GT(sheet.source_line, 0);
}

TEST(BuiltInScenes, DrapeIsAnUnpinnedSheetHalfAMetreAboveASphere) {
  const SceneDescription scene = LoadBuiltInScene("drape");
  ASSERT_EQ(scene.garments.size(), 1u);
  const sim::GarmentSpec& sheet = scene.garments[0];
  EXPECT_TRUE(sheet.pin_points.empty());
  ASSERT_TRUE(sheet.panel.has_value());
  EXPECT_EQ(sheet.panel->origin, Eigen::Vector3d(-0.5, 0.5, -0.5));
  EXPECT_EQ(sheet.panel->cols, 33);
  ASSERT_EQ(scene.spheres.size(), 1u);
  EXPECT_EQ(scene.spheres[0].center, Eigen::Vector3d::Zero());
  EXPECT_EQ(scene.spheres[0].radius, 0.25);
  EXPECT_EQ(scene.spheres[0].thickness, 0.005);
  EXPECT_GT(scene.spheres[0].source_line, 0);
}

TEST(BuiltInScenes, DemoIsTheHangingSheetSwingingOntoASphereForFourSeconds) {
  const SceneDescription scene = LoadBuiltInScene("demo");
  EXPECT_EQ(scene.duration, 4.0);
  ASSERT_EQ(scene.garments.size(), 1u);
  EXPECT_EQ(scene.garments[0].pin_points.size(), 2u);
  ASSERT_EQ(scene.spheres.size(), 1u);
  // The sphere must reach through the plane z = -0.5 the sheet hangs in, or the sheet
  // would slide off it instead of settling on it.
  EXPECT_LT(scene.spheres[0].center.z() - scene.spheres[0].radius, -0.5);
  EXPECT_LT(scene.spheres[0].center.y(), 0.0);
}

TEST(BuiltInSceneNames, ListsDemoHangDrapeAndGarment) {
  EXPECT_EQ(BuiltInSceneNames(), (std::vector<std::string>{"demo", "hang", "drape", "garment"}));
}

TEST(BuiltInSceneText, RefusesUnknownNameListingKnownOnes) {
  try {
    BuiltInSceneText("hnag");
    FAIL() << "accepted an unknown scene";
  } catch (const InputError& error) {
    EXPECT_TRUE(Contains(error.what(), "hnag"));
    EXPECT_TRUE(Contains(error.what(), "\"demo\", \"hang\", \"drape\""));
  }
}

TEST(BuiltInSceneText, EqualsTheSceneFilesInTheRepository) {
  for (const std::string& name : BuiltInSceneNames()) {
    EXPECT_EQ(BuiltInSceneText(name), ReadFile("scenes/" + name + ".toml")) << name;
  }
}

TEST(LoadSceneFile, ReadsTheSameSceneAsTheEmbeddedText) {
  const SceneDescription from_file = LoadSceneFile("scenes/hang.toml");
  EXPECT_EQ(from_file.source, "scenes/hang.toml");
  ExpectSameScene(from_file, ParseSceneText(BuiltInSceneText("hang"), "hang", ""));
}

TEST(LoadSceneFile, RefusesAMissingFileNamingIt) {
  try {
    LoadSceneFile("scenes/no_such_scene.toml");
    FAIL() << "accepted a missing file";
  } catch (const InputError& error) {
    EXPECT_TRUE(Contains(error.what(), "scenes/no_such_scene.toml"));
  }
}

// ---- values and defaults ----------------------------------------------------------------

TEST(ParseSceneText, FillsOmittedKeysWithTheDocumentedDefaults) {
  const SceneDescription scene = ParseSceneText(kMinimalScene, "dir/my_scene.toml", "dir");
  EXPECT_EQ(scene.name, "my_scene");  // the file name when the scene has none
  EXPECT_EQ(scene.source, "dir/my_scene.toml");
  EXPECT_EQ(scene.duration, 2.0);
  EXPECT_EQ(scene.frame_rate, 60.0);
  EXPECT_EQ(scene.solver.tolerance, 1e-2);
  EXPECT_EQ(scene.solver.max_iterations, 1000);
  EXPECT_TRUE(scene.effects.air_drag);
  EXPECT_FALSE(scene.effects.self_collision);
  ASSERT_EQ(scene.garments.size(), 1u);
  EXPECT_EQ(scene.garments[0].material, "stiff_cotton");
  EXPECT_EQ(scene.garments[0].pin_tolerance, 1e-3);
  EXPECT_EQ(scene.garments[0].source_line, 2);
  ASSERT_TRUE(scene.garments[0].panel.has_value());
  EXPECT_EQ(scene.garments[0].panel->cols, 33);
  EXPECT_EQ(scene.garments[0].panel->u_axis, Eigen::Vector3d::UnitX());
}

TEST(ParseSceneText, AcceptsIntegersWhereNumbersAreExpected) {
  const SceneDescription scene = ParseSceneText(
      "duration = 3\ngravity = [0, -10, 0]\n" + std::string(kMinimalScene) + "size = [2, 1]\n",
      "test.toml", "");
  EXPECT_EQ(scene.duration, 3.0);
  EXPECT_EQ(scene.gravity, Eigen::Vector3d(0.0, -10.0, 0.0));
  EXPECT_EQ(scene.garments[0].panel->width, 2.0);
}

TEST(ParseSceneText, ReadsSceneMaterialsStartingFromTheirBase) {
  const std::string text = R"toml(
[[material]]
name = "silk"
density = 0.05
[[material]]
name = "blender_like"
base = "blender_cotton"
[[garment]]
name = "scarf"
material = "silk"
[garment.panel]
)toml";
  const SceneDescription scene = ParseSceneText(text, "test.toml", "");
  ASSERT_EQ(scene.materials.size(), 2u);
  EXPECT_EQ(scene.materials[0].name, "silk");
  EXPECT_EQ(scene.materials[0].density, 0.05);
  EXPECT_EQ(scene.materials[0].stretch_stiffness, sim::Material{}.stretch_stiffness);
  EXPECT_EQ(scene.materials[1].name, "blender_like");
  EXPECT_GT(scene.materials[1].structural_spring_k, 0.0);
  EXPECT_EQ(scene.garments[0].material, "silk");
}

TEST(ParseSceneText, NormalisesPanelAxes) {
  const SceneDescription scene = ParseSceneText(
      std::string(kMinimalScene) + "u_axis = [2, 0, 0]\nv_axis = [0, 3, 0]\n", "test.toml", "");
  EXPECT_EQ(scene.garments[0].panel->u_axis, Eigen::Vector3d::UnitX());
  EXPECT_EQ(scene.garments[0].panel->v_axis, Eigen::Vector3d::UnitY());
}

// ---- errors point at the line and field -------------------------------------------------

TEST(ParseSceneText, PointsAtLineFieldAndValueOfAnOutOfRangeNumber) {
  const std::string text = R"toml(name = "bad"
[[material]]
name = "silk"
density = -1
[[garment]]
name = "sheet"
material = "silk"
[garment.panel]
)toml";
  const std::string message = ErrorOf(text);
  EXPECT_TRUE(Contains(message, "test.toml:4:1: material[0].density = -1 kg/m²"));
  EXPECT_TRUE(Contains(message, "(0, 100000]"));
}

TEST(ParseSceneText, StatesTheAllowedRangeOfEachField) {
  struct Case {
    std::string lines;  // put before the garment: TOML keys belong to the table above them
    std::string field;
    std::string range;
  };
  const Case cases[] = {
      {"duration = 4000", "duration = 4000 s", "(0, 3600]"},
      {"frame_rate = 0.5", "frame_rate = 0.5 Hz", "[1, 1000]"},
      {"[solver]\ntolerance = 2", "solver.tolerance = 2", "[1e-12, 1)"},
      {"[solver]\ntolerance = 1e-300", "solver.tolerance = 1e-300", "[1e-12, 1)"},
      {"[solver]\nmax_iterations = 0", "solver.max_iterations = 0", "[1, 100000]"},
      {"[solver]\nsubsteps = 5000", "solver.substeps = 5000", "[1, 1000]"},
      {"[[sphere]]\nradius = 0", "sphere[0].radius = 0 m", "(0, 10000]"},
      {"[[sphere]]\nthickness = -0.1", "sphere[0].thickness = -0.1 m", "[0, 0.05]"},
      // Values a damaged scene file ran with, silently (tools/fuzz_import.py's damage): the
      // cloth stretched 1.9e12 % round a sphere 2e9 m thick, 66 million % under 1e9 m/s².
      {"[[sphere]]\nthickness = 2147483648", "sphere[0].thickness = 2147483648 m", "[0, 0.05]"},
      {"[[sphere]]\nradius = 1e308", "sphere[0].radius = 1e+308 m", "(0, 10000]"},
      {"[[sphere]]\nfriction = 1e308", "sphere[0].friction = 1e+308", "[0, 2]"},
      {"[[sphere]]\ncenter = [0, -1e308, 0]", "sphere[0].center[1] = -1e+308 m",
       "[-10000, 10000]"},
      {"gravity = [0, -999999999, 0]", "gravity[1] = -999999999 m/s²", "[-100, 100]"},
      {"[[material]]\nname = \"m\"\ndamping = -1", "material[0].damping = -1 s", "[0, 10]"},
      {"[[material]]\nname = \"m\"\nstretch_stiffness = 1e308",
       "material[0].stretch_stiffness = 1e+308 N/m", "[0, 1e+08]"},
      {"[[material]]\nname = \"m\"\ndensity = 1e300", "material[0].density = 1e+300 kg/m²",
       "(0, 100000]"},
      {"[[material]]\nname = \"m\"\nfriction = 3", "material[0].friction = 3", "[0, 2]"},
  };
  for (const Case& c : cases) {
    const std::string text = c.lines + "\n" + kMinimalScene;
    const std::string message = ErrorOf(text);
    const std::string bad_line = c.lines.substr(c.lines.rfind('\n') + 1);
    EXPECT_TRUE(Contains(message, LocationOf(text, bad_line))) << c.lines;
    EXPECT_TRUE(Contains(message, c.field)) << c.lines;
    EXPECT_TRUE(Contains(message, c.range)) << c.lines;
  }
}

TEST(ParseSceneText, RefusesOutOfRangePanelValuesNamingTheElement) {
  const std::string text = std::string(kMinimalScene) + "size = [1.0, -2]\n";
  EXPECT_TRUE(Contains(ErrorOf(text), "garment[0].panel.size[1] = -2 m"));
  const std::string resolution = std::string(kMinimalScene) + "resolution = [33, 2000]\n";
  const std::string message = ErrorOf(resolution);
  EXPECT_TRUE(Contains(message, LocationOf(resolution, "resolution")));
  EXPECT_TRUE(Contains(message, "garment[0].panel.resolution[1] = 2000"));
  EXPECT_TRUE(Contains(message, "[2, 1025]"));
}

TEST(ParseSceneText, RefusesUnknownKeyListingAllowedOnes) {
  const std::string text =
      "[solver]\nmethod = \"pcg\"\ntolerence = 0.5\n" + std::string(kMinimalScene);
  const std::string message = ErrorOf(text);
  EXPECT_TRUE(Contains(message, "test.toml:3:1: solver.tolerence = 0.5"));
  EXPECT_TRUE(Contains(message, "unknown key"));
  EXPECT_TRUE(Contains(message, "method, tolerance, max_iterations, levels, coarse_operator, "
                                "substeps, strain_limit"));
}

TEST(ParseSceneText, ReadsTheMultigridCoarseOperatorRediscretisedByDefault) {
  EXPECT_EQ(ParseSceneText(kMinimalScene, "test.toml", "").solver.coarse_operator,
            sim::CoarseOperator::kRediscretised);
  const std::string text = "[solver]\nmethod = \"multigrid\"\ncoarse_operator = \"galerkin\"\n" +
                           std::string(kMinimalScene);
  EXPECT_EQ(ParseSceneText(text, "test.toml", "").solver.coarse_operator,
            sim::CoarseOperator::kGalerkin);
  const std::string bad = "[solver]\ncoarse_operator = \"exact\"\n" + std::string(kMinimalScene);
  const std::string message = ErrorOf(bad);
  EXPECT_TRUE(Contains(message, "solver.coarse_operator"));
  EXPECT_TRUE(Contains(message, "galerkin"));
  EXPECT_TRUE(Contains(message, "rediscretised"));
}

TEST(ParseSceneText, ReadsTheSolverThreadsTheMachinesByDefaultAndRefusesThemOutOfRange) {
  EXPECT_EQ(ParseSceneText(kMinimalScene, "test.toml", "").solver.threads, sim::kMachineThreads);
  const std::string two = "[solver]\nthreads = 2\n" + std::string(kMinimalScene);
  EXPECT_EQ(ParseSceneText(two, "test.toml", "").solver.threads, 2);
  const std::string many = "[solver]\nthreads = 65\n" + std::string(kMinimalScene);
  const std::string message = ErrorOf(many);
  EXPECT_TRUE(Contains(message, "test.toml:2:1: solver.threads = 65")) << message;
  EXPECT_TRUE(Contains(message, "64")) << message;
}

TEST(ParseSceneText, RefusesAMisspelledTableListingAllowedKeys) {
  const std::string text = "[[garment]]\nname = \"a\"\n[garment.pannel]\n";
  const std::string message = ErrorOf(text);
  EXPECT_TRUE(Contains(message, "test.toml:3:"));
  EXPECT_TRUE(Contains(message, "garment[0].pannel"));
  EXPECT_TRUE(Contains(message, "panel, mesh"));
}

TEST(ParseSceneText, ReportsTomlSyntaxErrorsWithTheirLine) {
  const std::string text = "name = \"x\"\nduration = [1,\n\n[[garment]]\n";
  const std::string message = ErrorOf(text);
  EXPECT_TRUE(Contains(message, "test.toml:"));
  EXPECT_TRUE(Contains(message, "TOML syntax error"));
  const std::string redefined = "duration = 1\nduration = 2\n";
  EXPECT_TRUE(Contains(ErrorOf(redefined), "test.toml:2:"));
}

TEST(ParseSceneText, RefusesWrongTypesNamingTheExpectedOne) {
  EXPECT_TRUE(Contains(ErrorOf("duration = \"2\"\n" + std::string(kMinimalScene)),
                       "test.toml:1:1: duration = \"2\" s: expected a number, found a string"));
  EXPECT_TRUE(Contains(ErrorOf(std::string(kMinimalScene) + "resolution = [33.0, 33]\n"),
                       "resolution[0] = 33: expected an integer, found a float"));
  EXPECT_TRUE(Contains(ErrorOf(std::string(kMinimalScene) + "origin = [0, 0]\n"),
                       "expected an array of 3 numbers [x, y, z], found 2 elements"));
  EXPECT_TRUE(Contains(ErrorOf("[effects]\nfriction = 1\n" + std::string(kMinimalScene)),
                       "effects.friction = 1: expected true or false, found an integer"));
  EXPECT_TRUE(Contains(ErrorOf("[solver]\nmethod = \"cg\"\n" + std::string(kMinimalScene)),
                       "must be one of \"pcg\", \"hierarchical\", \"multigrid\", \"direct\""));
  EXPECT_TRUE(Contains(ErrorOf("[material]\nname = \"silk\"\n" + std::string(kMinimalScene)),
                       "expected an array of tables, written [[material]]"));
}

TEST(ParseSceneText, RefusesNanAndInfinity) {
  EXPECT_TRUE(Contains(ErrorOf("duration = nan\n" + std::string(kMinimalScene)),
                       "test.toml:1:1: duration = nan s: must be a finite number"));
  EXPECT_TRUE(Contains(ErrorOf("gravity = [0, -inf, 0]\n" + std::string(kMinimalScene)),
                       "gravity[1] = -inf m/s²: must be a finite number"));
  const std::string pins =
      "[[garment]]\nname = \"sheet\"\npin_points = [[0, 0, 0],\n  [0, nan, 0]]\n[garment.panel]\n";
  EXPECT_TRUE(Contains(ErrorOf(pins), LocationOf(pins, "  [0, nan")));
  EXPECT_TRUE(Contains(ErrorOf(pins), "garment[0].pin_points[1][1] = nan m"));
}

TEST(ParseSceneText, RefusesASceneWithoutGarments) {
  EXPECT_TRUE(Contains(ErrorOf("duration = 1\n"), "test.toml:1:1: garment: missing"));
}

TEST(ParseSceneText, RefusesAMissingRequiredKeyPointingAtItsTable) {
  const std::string text =
      "duration = 1\n\n[[garment]]\nmaterial = \"stiff_cotton\"\n[garment.panel]\n";
  EXPECT_TRUE(Contains(ErrorOf(text), "test.toml:3:1: garment[0].name: missing"));
}

TEST(ParseSceneText, RefusesAnUnknownMaterialListingKnownOnes) {
  const std::string text = R"toml(
[[material]]
name = "silk"
[[garment]]
name = "sheet"
material = "slik"
[garment.panel]
)toml";
  const std::string message = ErrorOf(text);
  EXPECT_TRUE(Contains(message, LocationOf(text, "material = \"slik\"")));
  EXPECT_TRUE(Contains(message, "garment[0].material = \"slik\""));
  EXPECT_TRUE(Contains(message, "silk, cotton, wool, denim, leather, stiff_cotton, blender_cotton"));
}

TEST(ParseSceneText, RefusesDuplicateMaterialAndGarmentNames) {
  const std::string materials =
      "[[material]]\nname = \"silk\"\n[[material]]\nname = \"silk\"\n" + std::string(kMinimalScene);
  EXPECT_TRUE(
      Contains(ErrorOf(materials), "test.toml:4:1: material[1].name = \"silk\": duplicate"));
  const std::string garments = std::string(kMinimalScene) + kMinimalScene;
  EXPECT_TRUE(Contains(ErrorOf(garments), "garment[1].name = \"sheet\": duplicate"));
}

TEST(ParseSceneText, RefusesAGarmentWithMoreOrLessThanOneShape) {
  const std::string neither = "[[garment]]\nname = \"sheet\"\n";
  EXPECT_TRUE(Contains(ErrorOf(neither), "test.toml:1:1: garment[0] \"sheet\": needs exactly one of"));
  const std::string both = std::string(kMinimalScene) + "[garment.mesh]\nfile = \"skirt.obj\"\n";
  EXPECT_TRUE(Contains(ErrorOf(both), "needs exactly one of [garment.panel], [garment.mesh] and pattern"));
}

TEST(ParseSceneText, ReadsTheAvatarAndAPatternGarment) {
  const sim::SceneDescription scene = LoadBuiltInScene("garment");
  ASSERT_TRUE(scene.avatar.has_value());
  EXPECT_EQ(scene.avatar->clip->name, "walk");
  EXPECT_EQ(scene.avatar->collision, sim::BodyCollisionMethod::kMesh);
  EXPECT_EQ(scene.garments.at(0).pattern.value_or(""), "skirt");
}

TEST(ParseSceneText, ReadsThePostureInDegreesAndRefusesUnknownJointsAndTurnsBeyondOne) {
  const std::string base = "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n[avatar]\n";
  const sim::SceneDescription scene =
      ParseSceneText(base + "[avatar.posture]\nl_shoulder = [0, 0, 90]\n", "test.toml", "");
  const sim::Skeleton& skeleton = scene.avatar->avatar->skeleton();
  const Eigen::Quaterniond q =
      scene.avatar->motion.posture.rotations[skeleton.Find(sim::HAnimJoint::kLShoulder)];
  // 90° about z takes x to y (hand computation).
  EXPECT_LT((q * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-12);
  EXPECT_TRUE(Contains(ErrorOf(base + "[avatar.posture]\nl_shoulde = [0, 0, 1]\n"),
                       "avatar.posture.l_shoulde"));
  // A turn and more is a typing error, as for the heading.
  const std::string huge = ErrorOf(base + "[avatar.posture]\nl_elbow = [0, 1e300, 0]\n");
  EXPECT_TRUE(Contains(huge, "test.toml:6")) << huge;
  EXPECT_TRUE(Contains(huge, "avatar.posture.l_elbow")) << huge;
  EXPECT_TRUE(Contains(huge, "-360")) << huge;
  EXPECT_TRUE(Contains(ErrorOf(base + "[avatar.posture]\nl_elbow = [0, 0, -360.5]\n"), "-360"));
  EXPECT_NO_THROW(ParseSceneText(base + "[avatar.posture]\nl_elbow = [360, 0, -360]\n",
                                 "test.toml", ""));
}

TEST(ParseSceneText, ReadsTheSuperquadricMapMemoryAndRefusesItOutOfRange) {
  const std::string base = "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n[avatar]\n";
  EXPECT_EQ(ParseSceneText(base, "test.toml", "").avatar->superquadric_map_mb, 256.0);
  EXPECT_EQ(ParseSceneText(base + "superquadric_map_mb = 0\n", "test.toml", "")
                .avatar->superquadric_map_mb,
            0.0);
  const std::string message = ErrorOf(base + "superquadric_map_mb = -1\n");
  EXPECT_TRUE(Contains(message, "avatar.superquadric_map_mb = -1")) << message;
  EXPECT_TRUE(Contains(message, "16384")) << message;
}

TEST(ParseSceneText, ReadsTheSkinTravelPerStepAndRefusesItOutOfRange) {
  const std::string base = "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n[avatar]\n";
  const sim::AvatarSpec defaults = *ParseSceneText(base, "test.toml", "").avatar;
  EXPECT_EQ(defaults.max_skin_travel, 0.05);
  EXPECT_EQ(defaults.max_steps_per_frame, 8);
  const sim::AvatarSpec set = *ParseSceneText(
      base + "max_skin_travel = 0\nmax_steps_per_frame = 3\n", "test.toml", "").avatar;
  EXPECT_EQ(set.max_skin_travel, 0.0);
  EXPECT_EQ(set.max_steps_per_frame, 3);
  const std::string travel = ErrorOf(base + "max_skin_travel = -0.01\n");
  EXPECT_TRUE(Contains(travel, "avatar.max_skin_travel = -0.01")) << travel;
  const std::string steps = ErrorOf(base + "max_steps_per_frame = 65\n");
  EXPECT_TRUE(Contains(steps, "avatar.max_steps_per_frame = 65")) << steps;
  EXPECT_TRUE(Contains(steps, "64")) << steps;
}

TEST(ParseSceneText, ReadsTheArmSpreadAsAutoOrDegreesAndRefusesOthers) {
  const std::string base = "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n[avatar]\n";
  const sim::AvatarSpec defaults = *ParseSceneText(base, "test.toml", "").avatar;
  EXPECT_TRUE(defaults.auto_arm_spread);
  EXPECT_TRUE(ParseSceneText(base + "arm_spread = \"auto\"\n", "test.toml", "")
                  .avatar->auto_arm_spread);
  const sim::AvatarSpec set =
      *ParseSceneText(base + "arm_spread = 15\n", "test.toml", "").avatar;
  EXPECT_FALSE(set.auto_arm_spread);
  EXPECT_NEAR(set.motion.arm_spread[0], 15.0 * M_PI / 180.0, 1e-15);
  EXPECT_NEAR(set.motion.arm_spread[1], 15.0 * M_PI / 180.0, 1e-15);
  EXPECT_FALSE(ParseSceneText(base + "arm_spread = 0\n", "test.toml", "").avatar->auto_arm_spread);
  const std::string wide = ErrorOf(base + "arm_spread = 31\n");
  EXPECT_TRUE(Contains(wide, "avatar.arm_spread = 31")) << wide;
  EXPECT_TRUE(Contains(wide, "30")) << wide;
  const std::string word = ErrorOf(base + "arm_spread = \"wide\"\n");
  EXPECT_TRUE(Contains(word, "avatar.arm_spread")) << word;
  EXPECT_TRUE(Contains(word, "auto")) << word;
}

TEST(ParseSceneText, RefusesAPatternWithoutAvatarAndAnUnknownClip) {
  const std::string pattern = "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n";
  EXPECT_TRUE(Contains(ErrorOf(pattern), "test.toml:1: garment[0].pattern = \"skirt\": a pattern "
                                         "garment is fitted to an avatar, and the scene has none"));
  const std::string clip = pattern + "[avatar]\nclip = \"waltz\"\n";
  const std::string message = ErrorOf(clip);
  EXPECT_TRUE(Contains(message, "avatar.clip = \"waltz\""));
  EXPECT_TRUE(Contains(message, "\"walk\""));
  EXPECT_TRUE(Contains(message, "\"dance\""));
}

TEST(ParseSceneText, RefusesZeroAndSkewPanelAxes) {
  const std::string zero = std::string(kMinimalScene) + "u_axis = [0, 0, 0]\n";
  EXPECT_TRUE(Contains(ErrorOf(zero), "garment[0].panel.u_axis = [0, 0, 0]: must be a non-zero"));
  const std::string skew = std::string(kMinimalScene) + "u_axis = [1, 0, 0]\nv_axis = [1, 0, 1]\n";
  const std::string message = ErrorOf(skew);
  EXPECT_TRUE(Contains(message, LocationOf(skew, "v_axis")));
  EXPECT_TRUE(Contains(message, "orthogonal"));
}

// ---- mesh garments ----------------------------------------------------------------------

TEST(ParseSceneText, MeshGarmentWithAMissingFileNamesTheSceneLineAndTheMeshPath) {
  const std::string text = R"toml(
[[garment]]
name = "skirt"
[garment.mesh]
scale = 0.1
file = "no_such_skirt.obj"
)toml";
  const std::string message = ErrorOf(text, "costumes");
  EXPECT_TRUE(Contains(message, LocationOf(text, "file =")));
  EXPECT_TRUE(Contains(message, "garment[0].mesh.file = \"no_such_skirt.obj\""));
  EXPECT_TRUE(Contains(message, "costumes/no_such_skirt.obj"));
}

TEST(LoadSceneFile, ReadsMeshGarmentsRelativeToTheSceneFile) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "costume_scene_file_test";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "square.obj") << "v 0 0 0\nv 10 0 0\nv 10 0 10\nv 0 0 10\nf 1 2 3 4\n";
  std::ofstream(dir / "scene.toml") << "[[garment]]\nname = \"square\"\n"
                                       "[garment.mesh]\nfile = \"square.obj\"\nscale = 0.1\n"
                                       "offset = [0, 1, 0]\n";
  const SceneDescription scene = LoadSceneFile((dir / "scene.toml").string());
  ASSERT_EQ(scene.garments.size(), 1u);
  ASSERT_TRUE(scene.garments[0].mesh.has_value());
  const sim::SurfaceMesh& mesh = *scene.garments[0].mesh;
  ASSERT_EQ(mesh.vertices.rows(), 4);
  EXPECT_NEAR(mesh.vertices.col(0).maxCoeff(), 1.0, 1e-12);
  EXPECT_NEAR(mesh.vertices.col(1).minCoeff(), 1.0, 1e-12);
  EXPECT_FALSE(scene.garments[0].fit_outside_body);
  std::filesystem::remove_all(dir);
}

// fit_outside_body is read from [garment.mesh]; without an avatar to fit to it is refused,
// pointing at the garment.
TEST(LoadSceneFile, ReadsFitOutsideBodyAndRefusesItWithoutAvatar) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "costume_scene_file_fit_test";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "square.obj") << "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nf 1 2 3 4\n";
  const std::string garment =
      "[[garment]]\nname = \"square\"\n[garment.mesh]\nfile = \"square.obj\"\n"
      "fit_outside_body = true\n";
  std::ofstream(dir / "fitted.toml") << "[avatar]\n" << garment;
  const SceneDescription scene = LoadSceneFile((dir / "fitted.toml").string());
  ASSERT_EQ(scene.garments.size(), 1u);
  EXPECT_TRUE(scene.garments[0].fit_outside_body);

  std::ofstream(dir / "bare.toml") << garment;
  try {
    LoadSceneFile((dir / "bare.toml").string());
    ADD_FAILURE() << "fit_outside_body without an avatar was accepted";
  } catch (const InputError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("fit_outside_body"), std::string::npos) << message;
    EXPECT_NE(message.find("avatar"), std::string::npos) << message;
  }
  std::filesystem::remove_all(dir);
}

// ---- avatar and clip files ----------------------------------------------------------------

/// A BVH clip on an H-Anim-named skeleton (root, hips, knees, shoulders, elbows: the joints
/// retargeting needs), `frames` frames at 1/30 s, the root rising 1 cm a frame.
std::string HAnimBvh(int frames) {
  std::ostringstream bvh;
  bvh << "HIERARCHY\nROOT humanoid_root\n{\n OFFSET 0 90 0\n"
         " CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n";
  const auto limb = [&](const std::string& upper, const std::string& lower, double x, double y,
                        double length) {
    bvh << " JOINT " << upper << "\n {\n  OFFSET " << x << " " << y << " 0\n"
        << "  CHANNELS 3 Zrotation Xrotation Yrotation\n  JOINT " << lower << "\n  {\n"
        << "   OFFSET 0 " << -length << " 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
        << "   End Site\n   {\n    OFFSET 0 " << -length << " 0\n   }\n  }\n }\n";
  };
  limb("l_hip", "l_knee", 10, 0, 45);
  limb("r_hip", "r_knee", -10, 0, 45);
  limb("l_shoulder", "l_elbow", 18, 50, 28);
  limb("r_shoulder", "r_elbow", -18, 50, 28);
  bvh << "}\nMOTION\nFrames: " << frames << "\nFrame Time: 0.0333333\n";
  for (int f = 0; f < frames; ++f) {
    bvh << "0 " << 90 + f << " 0 0 0 0";
    for (int i = 0; i < 8 * 3; ++i) bvh << " 0";
    bvh << "\n";
  }
  return bvh.str();
}

// [avatar] names a clip file relative to the scene file; it is read, and checked to be
// playable on the avatar where the scene names it.
TEST(LoadSceneFile, ReadsAClipFileRelativeToTheSceneFile) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "costume_scene_file_clip_test";
  std::filesystem::create_directories(dir / "clips");
  std::ofstream(dir / "clips" / "rise.bvh") << HAnimBvh(12);
  const std::string garment = "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n";
  std::ofstream(dir / "scene.toml") << "[avatar]\nclip = \"clips/rise.bvh\"\n" << garment;
  const SceneDescription scene = LoadSceneFile((dir / "scene.toml").string());
  ASSERT_TRUE(scene.avatar && scene.avatar->clip);
  EXPECT_EQ(scene.avatar->clip->frames.size(), 12u);  // the file's "Frames: 12"
  EXPECT_NEAR(scene.avatar->clip->frame_time, 1.0 / 30.0, 1e-6);

  // A clip whose skeleton maps too few H-Anim joints is refused at its line.
  std::ofstream(dir / "clips" / "alone.bvh")
      << "HIERARCHY\nROOT alone\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n"
         " End Site\n {\n  OFFSET 0 10 0\n }\n}\nMOTION\nFrames: 2\nFrame Time: 0.1\n"
         "0 0 0\n0 1 0\n";
  std::ofstream(dir / "alone.toml") << garment << "[avatar]\nclip = \"clips/alone.bvh\"\n";
  try {
    LoadSceneFile((dir / "alone.toml").string());
    ADD_FAILURE() << "a clip no avatar can play was accepted";
  } catch (const InputError& error) {
    EXPECT_TRUE(Contains(error.what(), "alone.toml:5:1: avatar.clip = \"clips/alone.bvh\": "
                                       "cannot be put on the avatar"));
  }
  std::filesystem::remove_all(dir);
}

TEST(ParseSceneText, RefusesMissingAvatarAndClipFilesListingTheBuiltIns) {
  const std::string garment = "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n";
  const std::string model = ErrorOf(garment + "[avatar]\nmodel = \"body.glb\"\n", "people");
  EXPECT_TRUE(Contains(model, "avatar.model = \"body.glb\": must be one of \"builtin\", or an "
                              "avatar file (.glb .gltf .fbx .dae .obj); no file "
                              "\"people/body.glb\""));
  const std::string clip = ErrorOf(garment + "[avatar]\nclip = \"wlak\"\n");
  EXPECT_TRUE(Contains(clip, "avatar.clip = \"wlak\": must be one of \"none\", \"stand\", "
                             "\"walk\""));
  EXPECT_TRUE(Contains(clip, "or a clip file (.bvh"));
  // MakeHuman's skeleton and weights come together, and only with a model file.
  EXPECT_TRUE(Contains(ErrorOf(garment + "[avatar]\nweights = \"w.mhw\"\n"),
                       "avatar.weights = \"w.mhw\": only with a MakeHuman model file"));
}

// The catalogue's garment files name no avatar or clip file: a stored path would be read
// wherever the garment is loaded.
TEST(ParseSceneText, RefusesAvatarFilesWhereTheCallerForbidsThem) {
  const std::string text = "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n"
                           "[avatar]\nclip = \"/etc/passwd\"\n";
  try {
    ParseSceneText(text, "test.toml", "", AvatarFiles::kRefused);
    ADD_FAILURE() << "a clip file was accepted in a garment file";
  } catch (const InputError& error) {
    EXPECT_TRUE(Contains(error.what(), "test.toml:5:1: avatar.clip = \"/etc/passwd\": must be "
                                       "one of"));
    EXPECT_TRUE(Contains(error.what(), "a garment file names no avatar or clip file"));
  }
  // The built-ins stay allowed there.
  const std::string built_in = "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n"
                               "[avatar]\nmodel = \"builtin\"\nclip = \"walk\"\n";
  EXPECT_NO_THROW(ParseSceneText(built_in, "test.toml", "", AvatarFiles::kRefused));
}

const std::filesystem::path kMakeHumanBody =
    std::filesystem::absolute(test::kSharedData / "makehuman" / "body");

/// Loads `text` as the file scene.toml of a scratch folder, after an [avatar] table naming
/// the MakeHuman triple of ../shared/data and `avatar_extra` lines.
SceneDescription LoadOnMakeHuman(const std::string& avatar_extra, const std::string& text) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "costume_scene_file_makehuman_test";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "scene.toml")
      << "[avatar]\nmodel = \"" << (kMakeHumanBody / "base.obj").string() << "\"\nskeleton = \""
      << (kMakeHumanBody / "default.mhskel").string() << "\"\nweights = \""
      << (kMakeHumanBody / "default_weights.mhw").string() << "\"\n"
      << avatar_extra << text;
  const SceneDescription scene = LoadSceneFile((dir / "scene.toml").string());
  std::filesystem::remove_all(dir);
  return scene;
}

// The MakeHuman triple from ../shared/data: the avatar the importer reads, its body's
// vertex count that of base.obj's "body" group (counted here from the file's faces).
TEST(LoadSceneFile, ReadsTheMakeHumanTripleWithABuiltInClip) {
  const std::filesystem::path& body = kMakeHumanBody;
  if (!std::filesystem::exists(body / "base.obj")) GTEST_SKIP() << "no " << body;
  const SceneDescription scene =
      LoadOnMakeHuman("clip = \"walk\"\n", "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\n");
  ASSERT_TRUE(scene.avatar && scene.avatar->clip);
  // base.obj's "body" group: the distinct vertices its faces use.
  std::ifstream obj(body / "base.obj");
  std::string line, group;
  std::set<long> used;
  while (std::getline(obj, line)) {
    if (line.rfind("g ", 0) == 0) group = line.substr(2);
    if (line.rfind("f ", 0) != 0 || group != "body") continue;
    std::istringstream corners(line.substr(2));
    std::string corner;
    while (corners >> corner) used.insert(std::stol(corner.substr(0, corner.find('/'))));
  }
  ASSERT_FALSE(used.empty());
  EXPECT_EQ(static_cast<std::size_t>(scene.avatar->avatar->rest_vertices().rows()), used.size());
  // Built-in clips are written for the built-in humanoid and retargeted onto this body.
  EXPECT_NE(scene.avatar->clip->skeleton.get(), scene.avatar->avatar->shared_skeleton().get());
  EXPECT_EQ(scene.avatar->clip->skeleton->num_joints(), sim::MakeHumanoidSkeleton()->num_joints());
}

// pin_waistband pins the mesh's open edge at the avatar's waist (and holds it by the pelvis):
// an open tube written here, its top ring at the built-in humanoid's vl5, its bottom 40 cm
// lower; exactly the top ring's 16 vertices are pinned.
TEST(LoadSceneFile, PinsTheWaistbandOfAMeshAtTheAvatarsWaist) {
  // Held by its pointer: a reference to *MakeHumanoidSkeleton() dangled once the temporary
  // pointer died (AddressSanitizer: heap-use-after-free).
  const std::shared_ptr<const sim::Skeleton> skeleton = sim::MakeHumanoidSkeleton();
  const double waist =
      skeleton->rest_world()[skeleton->Find(sim::HAnimJoint::kVl5)].translation().y();
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "costume_scene_file_waistband_test";
  std::filesystem::create_directories(dir);
  constexpr int kAround = 16;
  std::ofstream obj(dir / "tube.obj");
  std::vector<Eigen::Vector3d> top;
  for (int ring = 0; ring < 2; ++ring) {
    for (int i = 0; i < kAround; ++i) {
      const double angle = 2 * M_PI * i / kAround;
      const Eigen::Vector3d v(0.2 * std::cos(angle), waist - 0.4 * ring, 0.2 * std::sin(angle));
      if (ring == 0) top.push_back(v);
      obj << "v " << v.x() << " " << v.y() << " " << v.z() << "\n";
    }
  }
  for (int i = 0; i < kAround; ++i) {
    const int j = (i + 1) % kAround;
    obj << "f " << i + 1 << " " << j + 1 << " " << kAround + j + 1 << " " << kAround + i + 1
        << "\n";
  }
  obj.close();
  std::ofstream(dir / "scene.toml")
      << "[avatar]\n[[garment]]\nname = \"tube\"\npin_waistband = 0.05\n"
         "[garment.mesh]\nfile = \"tube.obj\"\n";
  const SceneDescription scene = LoadSceneFile((dir / "scene.toml").string());
  const sim::GarmentSpec& tube = scene.garments.at(0);
  ASSERT_EQ(tube.pin_points.size(), top.size());
  for (const Eigen::Vector3d& pin : tube.pin_points) {
    const auto match = std::find_if(top.begin(), top.end(), [&](const Eigen::Vector3d& v) {
      return (v - pin).norm() < 1e-5;
    });
    EXPECT_NE(match, top.end()) << pin.transpose();
  }
  EXPECT_EQ(tube.attach_to, sim::HAnimJoint::kSacroiliac);

  // A band that holds no edge, and a waistband without an avatar, are refused.
  const std::string tube_garment =
      "[[garment]]\nname = \"tube\"\npin_waistband = 0.05\n[garment.mesh]\nfile = \"tube.obj\"\n";
  EXPECT_TRUE(Contains(ErrorOf("[avatar]\nposition = [0, 1, 0]\n" + tube_garment, dir.string()),
                       "garment[0].pin_waistband = 0.05 m: no open edge"));
  EXPECT_TRUE(Contains(ErrorOf(tube_garment, dir.string()),
                       "needs [garment.mesh] and an [avatar]"));
  std::filesystem::remove_all(dir);
}

// A MakeHuman garment (.mhclo) is fitted to MakeHuman's body, which the avatar must be.
TEST(ParseSceneText, RefusesAMakeHumanGarmentOnAnotherAvatar) {
  const std::string text = "[avatar]\n[[garment]]\nname = \"suit\"\n[garment.mesh]\n"
                           "file = \"suit.mhclo\"\n";
  EXPECT_TRUE(Contains(ErrorOf(text), "garment[0].mesh.file = \"suit.mhclo\": a MakeHuman "
                                      "garment is fitted to MakeHuman's body"));
}

// The MakeHuman suit from ../shared/data in a scene file: MakeHuman's own fit of every
// vertex of its OBJ (counted here from the file's "v" lines), its waistband pinned.
TEST(LoadSceneFile, ReadsAMakeHumanGarmentOnTheMakeHumanBody) {
  const std::filesystem::path suit =
      kMakeHumanBody.parent_path() / "clothes" / "female_casualsuit02";
  if (!std::filesystem::exists(suit / "female_casualsuit02.mhclo")) GTEST_SKIP() << "no " << suit;
  const SceneDescription scene =
      LoadOnMakeHuman("", "[[garment]]\nname = \"suit\"\npin_waistband = 0.08\n[garment.mesh]\n"
                          "file = \"" + (suit / "female_casualsuit02.mhclo").string() + "\"\n");
  std::ifstream obj(suit / "female_casualsuit02.obj");
  long vertices = 0;
  for (std::string line; std::getline(obj, line);) vertices += line.rfind("v ", 0) == 0;
  const sim::GarmentSpec& garment = scene.garments.at(0);
  ASSERT_TRUE(garment.mesh);
  EXPECT_EQ(garment.mesh->vertices.rows(), vertices);
  // In metres on the body: within its height (base.obj's origin at the hips).
  EXPECT_LT(garment.mesh->vertices.col(1).maxCoeff(), 1.0);
  EXPECT_GT(garment.mesh->vertices.col(1).minCoeff(), -1.0);
  EXPECT_GT(garment.pin_points.size(), 10u);
}

// ---- the file-independent checks --------------------------------------------------------

TEST(ValidateScene, NamesTheSourceFieldAndRange) {
  SceneDescription scene = LoadBuiltInScene("hang");
  scene.source = "built-in";
  scene.solver.tolerance = 2.0;
  try {
    sim::ValidateScene(scene);
    FAIL() << "accepted tolerance 2";
  } catch (const InputError& error) {
    EXPECT_TRUE(Contains(error.what(), "built-in: solver.tolerance = 2: allowed range [1e-12, 1)"));
  }
}

TEST(ValidateScene, BoundsGravityAndTheSpheresAsTheFileParserDoes) {
  // Scenes built in code (the simulation server's) get the same ranges as files.
  const auto message = [](const SceneDescription& scene) {
    try {
      sim::ValidateScene(scene);
    } catch (const InputError& error) {
      return std::string(error.what());
    }
    return std::string();
  };
  SceneDescription scene = LoadBuiltInScene("drape");
  scene.source = "built-in";
  EXPECT_EQ(message(scene), "");
  scene.gravity = Eigen::Vector3d(0.0, -1e9, 0.0);
  EXPECT_TRUE(Contains(message(scene), "gravity = ")) << message(scene);
  EXPECT_TRUE(Contains(message(scene), "each coordinate within ±100")) << message(scene);
  scene = LoadBuiltInScene("drape");
  scene.spheres[0].thickness = 2147483648.0;
  EXPECT_TRUE(Contains(message(scene), "sphere[0].thickness = 2.14748e+09 m: allowed range "
                                       "[0, 0.05]"))
      << message(scene);
  scene = LoadBuiltInScene("drape");
  scene.spheres[0].center.x() = 1e308;
  EXPECT_TRUE(Contains(message(scene), "each coordinate within ±10000")) << message(scene);
}

// A duration rounding to no frame ran nothing and printed "median 0.00 ms/frame"; half a
// frame rounds to one.
TEST(ValidateScene, RefusesADurationOfNoFrame) {
  SceneDescription scene = LoadBuiltInScene("hang");
  scene.source = "built-in";
  scene.frame_rate = 50.0;
  scene.duration = 0.0099;
  try {
    sim::ValidateScene(scene);
    FAIL() << "accepted a duration of half a frame";
  } catch (const InputError& error) {
    EXPECT_TRUE(Contains(error.what(), "built-in: duration = 0.0099 s: less than half a frame at "
                                       "50 Hz, so no frame would be simulated (allowed: at least "
                                       "0.01 s)"))
        << error.what();
  }
  scene.duration = 0.01;
  EXPECT_NO_THROW(sim::ValidateScene(scene));
}

TEST(ValidateScene, RefusesAGarmentWithoutPanelOrMesh) {
  SceneDescription scene = LoadBuiltInScene("hang");
  scene.garments[0].panel.reset();
  EXPECT_THROW(sim::ValidateScene(scene), InputError);
  scene.garments.clear();
  EXPECT_THROW(sim::ValidateScene(scene), InputError);
}

TEST(SolverMethodName, SpellsTheMethodsAsTheSceneFileDoes) {
  EXPECT_STREQ(sim::SolverMethodName(sim::SolverMethod::kPcg), "pcg");
  EXPECT_STREQ(sim::SolverMethodName(sim::SolverMethod::kDirect), "direct");
}

// The presets are one table (sim_core/cloth/fabric_presets.h): KES-F cotton's EMT of 5 % at
// 490.3 N/m is a secant stiffness of 9,807 N/m, whether a [[material]] starts from it or a
// garment names it.
TEST(ParseSceneText, AMaterialStartsFromAFabricPresetAndAGarmentMayNameOne) {
  const auto garment = [](const std::string& material) {
    return "[[garment]]\nname = \"skirt\"\npattern = \"skirt\"\nmaterial = \"" + material +
           "\"\n[avatar]\n";
  };
  const sim::SceneDescription based = ParseSceneText(
      "[[material]]\nname = \"heavy\"\nbase = \"cotton\"\ndensity = 0.2\n" + garment("heavy"),
      "test.toml", "");
  ASSERT_EQ(based.materials.size(), 1u);
  EXPECT_NEAR(based.materials[0].stretch_stiffness, 490.3325 / 0.05, 1e-9);
  EXPECT_EQ(based.materials[0].density, 0.2);  // the table's own value over the preset's
  EXPECT_EQ(based.materials[0].friction, 0.4);
  const sim::SceneDescription named =
      ParseSceneText(garment("denim"), "test.toml", "");
  EXPECT_EQ(named.garments[0].material, "denim");
  EXPECT_TRUE(Contains(ErrorOf("[[material]]\nname = \"m\"\nbase = \"cottn\"\n"), "cotton"));
}

}  // namespace
}  // namespace costume::assets
