// The fast collision method's superquadrics fitted to a real body (paper §4, Solina & Bajcsy):
// the MakeHuman base body's segments, through the MakeHuman importer. Residuals are radial
// distances of the skin vertices from their segment's superquadric; the oracle is the
// best sphere about each segment's centroid, computed here independently, which the
// least-squares superquadric must beat, and an absolute bound of 3 cm: what is left (the
// torso's chest and shoulders, 27 mm RMS) is carried by the skin distance map, not the shape.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>

#include "assets/makehuman_import.h"
#include "sim_core/collision/superquadric_collider.h"

namespace costume {
namespace {

constexpr const char* kBody = "../shared/data/makehuman/body/";

/// RMS distance of `points` from the sphere about their centroid with their mean radius.
double BestSphereRms(const sim::Points& points) {
  const Eigen::RowVector3d centre = points.colwise().mean();
  const Eigen::VectorXd radii = (points.rowwise() - centre).rowwise().norm();
  return std::sqrt((radii.array() - radii.mean()).square().mean());
}

TEST(MakeHumanSuperquadrics, EverySegmentFitsItsSkinBetterThanASphereAndWithinThreeCentimetres) {
  if (!std::filesystem::exists(std::string(kBody) + "base.obj")) {
    GTEST_SKIP() << "../shared/data/makehuman not present";
  }
  const auto body = assets::LoadMakeHumanAvatar(std::string(kBody) + "base.obj",
                                                std::string(kBody) + "default.mhskel",
                                                std::string(kBody) + "default_weights.mhw");
  const std::vector<sim::SegmentSuperquadricFit> fits = sim::FitAvatarSegments(*body);
  int fitted = 0;
  for (const sim::SegmentSuperquadricFit& fit : fits) {
    if (!fit.fitted) continue;
    ++fitted;
    std::vector<int> members;
    for (int v = 0; v < body->num_vertices(); ++v) {
      if (body->vertex_segments()[v] == fit.segment) members.push_back(v);
    }
    sim::Points points(members.size(), 3);
    for (std::size_t i = 0; i < members.size(); ++i) points.row(i) = body->rest_vertices().row(members[i]);
    const double sphere = BestSphereRms(points);
    std::printf("%-14s %5d vertices: superquadric RMS %5.1f mm, max %5.1f mm; best sphere RMS %5.1f mm\n",
                std::string(sim::HAnimName(fit.segment)).c_str(), fit.num_vertices,
                1e3 * fit.fit.rms_radial_distance, 1e3 * fit.fit.max_radial_distance, 1e3 * sphere);
    EXPECT_LT(fit.fit.rms_radial_distance, 0.03) << sim::HAnimName(fit.segment);
    EXPECT_LT(fit.fit.rms_radial_distance, sphere) << sim::HAnimName(fit.segment);
  }
  EXPECT_GE(fitted, 14);  // every H-Anim segment but the root carries skin
}

}  // namespace
}  // namespace costume
