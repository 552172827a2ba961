// Built-in garments sewn around the built-in humanoid: they start outside the skin (checked
// against the skin itself with MeshDistance, not against the measures they were made from),
// their panels are sewn into closed tubes (only the waist/top and hem loops stay open), they
// hang from their top row, and their mass is density times their area.
#include "sim_core/avatar/garment_patterns.h"

#include <gtest/gtest.h>

#include <map>

#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/collision/mesh_distance.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

const std::shared_ptr<const Avatar>& Humanoid() {
  static const std::shared_ptr<const Avatar> humanoid = MakeHumanoid();
  return humanoid;
}

/// Edges used by exactly one triangle.
int BoundaryEdges(const ClothModelData& data) {
  std::map<std::pair<int, int>, int> uses;
  for (const Eigen::Vector3i& t : data.triangles) {
    for (int k = 0; k < 3; ++k) ++uses[std::minmax(t[k], t[(k + 1) % 3])];
  }
  int boundary = 0;
  for (const auto& [edge, count] : uses) boundary += count == 1;
  return boundary;
}

TEST(GarmentPatterns, EveryGarmentStartsOutsideTheSkinByAboutTheGap) {
  const Avatar& avatar = *Humanoid();
  MeshDistance skin("humanoid", avatar.rest_vertices(), avatar.triangles());
  const double gap = 0.015;
  for (const std::string& name : BuiltInGarmentNames()) {
    const GarmentPattern pattern = MakeBuiltInGarment(name, MeasureBody(avatar), Material{}, 48, gap);
    double nearest = 1e9;
    for (Eigen::Index p = 0; p < pattern.data.rest_positions.rows(); ++p) {
      nearest = std::min(nearest, skin.SignedDistance(pattern.data.rest_positions.row(p).transpose(), 0.5));
    }
    std::printf("%s: %zu particles, nearest to the skin %.1f mm\n", name.c_str(),
                static_cast<std::size_t>(pattern.data.masses.size()), 1e3 * nearest);
    EXPECT_GT(nearest, 0.5 * gap) << name;
  }
}

TEST(GarmentPatterns, TubesAreSewnShutAndHangFromTheirTopRow) {
  const BodyMeasures measures = MeasureBody(*Humanoid());
  for (const std::string name : {"skirt", "dress"}) {
    const GarmentPattern pattern = MakeBuiltInGarment(name, measures, Material{}, 48);
    const int around = 48;  // two panels of 25 columns share 2 seam columns
    EXPECT_EQ(static_cast<int>(pattern.attached.size()), around) << name;
    // Open only at the top and the hem: 2 loops of `around` edges.
    EXPECT_EQ(BoundaryEdges(pattern.data), 2 * around) << name;
    // Each row holds `around` particles: the seams' two columns became one.
    EXPECT_EQ(pattern.data.masses.size() % around, 0) << name;
    const double top = pattern.data.rest_positions.col(1).maxCoeff();
    for (int p : pattern.attached) EXPECT_DOUBLE_EQ(pattern.data.rest_positions(p, 1), top);
    EXPECT_NO_THROW(ClothModel::Create(pattern.data));
  }
  // The largest resolution (some 250,000 particles) is sewn shut the same way.
  const GarmentPattern largest = MakeBuiltInGarment("skirt", measures, Material{}, 1024);
  EXPECT_EQ(static_cast<int>(largest.attached.size()), 1024);
  EXPECT_EQ(BoundaryEdges(largest.data), 2 * 1024);
  EXPECT_EQ(largest.data.masses.size() % 1024, 0);
}

TEST(GarmentPatterns, MassIsDensityTimesTriangleArea) {
  Material material;
  material.density = 0.2;
  const GarmentPattern cape = MakeBuiltInGarment("cape", MeasureBody(*Humanoid()), material, 40);
  double area = 0.0;
  const Points& x = cape.data.rest_positions;
  for (const Eigen::Vector3i& t : cape.data.triangles) {
    area += 0.5 * (x.row(t[1]) - x.row(t[0])).cross(x.row(t[2]) - x.row(t[0])).norm();
  }
  EXPECT_NEAR(cape.data.masses.sum(), 0.2 * area, 1e-12);
}

TEST(GarmentPatterns, RefusesUnknownNamesListingTheBuiltInOnes) {
  try {
    MakeBuiltInGarment("kimono", MeasureBody(*Humanoid()), Material{});
    FAIL() << "no error";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("skirt, cape, dress"), std::string::npos) << error.what();
  }
}

/// The built-in humanoid with its rest pose (skeleton and skin) transformed by `transform`.
std::shared_ptr<const Avatar> Transformed(const Eigen::Affine3d& transform, double scale) {
  AvatarData data = Humanoid()->data();
  std::vector<Joint> joints = data.skeleton->joints();
  for (Joint& joint : joints) {
    joint.rest_local.translation() *= scale;
    if (joint.parent < 0) joint.rest_local = Eigen::Isometry3d(transform.linear()) * joint.rest_local;
  }
  data.skeleton = Skeleton::Create("moved", joints);
  for (Eigen::Index v = 0; v < data.rest_vertices.rows(); ++v) {
    data.rest_vertices.row(v) =
        (transform.linear() * (scale * data.rest_vertices.row(v).transpose())).transpose();
  }
  return Avatar::Create(data);
}

TEST(GarmentPatterns, MeasuringRefusesAnAvatarLyingDownOrOfTheWrongSizeNamingWhatIsWrong) {
  const auto lying = Transformed(
      Eigen::Affine3d(Eigen::AngleAxisd(-0.5 * 3.141592653589793, Eigen::Vector3d::UnitX())), 1.0);
  try {
    MeasureBody(*lying);
    ADD_FAILURE() << "a body lying along z was measured";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("not upright"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("up axis"), std::string::npos) << error.what();
  }
  const auto in_centimetres = Transformed(Eigen::Affine3d::Identity(), 100.0);
  try {
    MeasureBody(*in_centimetres);
    ADD_FAILURE() << "a body 170 m tall was measured";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("unit"), std::string::npos) << error.what();
  }
  EXPECT_NO_THROW(MeasureBody(*Transformed(Eigen::Affine3d::Identity(), 0.6)));  // a child
}

}  // namespace
}  // namespace costume::sim
