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

/// The superquadric is the segment's shape: along each of its axes it ends within 20 % of
/// the skin's half extent of the skin's ends, and its centre, where the collider's rays
/// start, lies in the middle third of the skin's extent. A limb's skin is an open tube whose
/// ends the fit's points do not show; MakeHuman's thighs and forearms had been fitted as the
/// wide halves of superquadrics twice their length centred at their thick ends.
void ExpectWithinItsSkin(const sim::Avatar& body, const sim::SegmentSuperquadricFit& fit,
                         const sim::Points& world) {
  const sim::Superquadric& shape = fit.fit.superquadric;
  const Eigen::Isometry3d to_local =
      (body.skeleton().rest_world()[fit.joint] * shape.frame).inverse(Eigen::Isometry);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (Eigen::Index i = 0; i < world.rows(); ++i) {
    const Eigen::Vector3d q = to_local * Eigen::Vector3d(world.row(i).transpose());
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  const Eigen::Vector3d size(shape.a1, shape.a2, shape.a3);
  const Eigen::Vector3d half = 0.5 * (hi - lo);
  for (int k = 0; k < 3; ++k) {
    const std::string what = std::string(sim::HAnimName(fit.segment)) + " axis " + std::to_string(k);
    EXPECT_LE(size[k], hi[k] + 0.2 * half[k]) << what;
    EXPECT_GE(-size[k], lo[k] - 0.2 * half[k]) << what;
  }
  // Along its length (the skin's longest extent): across a flat hand the skin's thickness
  // need not be centred.
  int k = 0;
  half.maxCoeff(&k);
  EXPECT_LT(lo[k] + half[k] * 2.0 / 3.0, 0.0) << sim::HAnimName(fit.segment);
  EXPECT_GT(hi[k] - half[k] * 2.0 / 3.0, 0.0) << sim::HAnimName(fit.segment);
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
    ExpectWithinItsSkin(*body, fit, points);
  }
  EXPECT_GE(fitted, 14);  // every H-Anim segment but the root carries skin
}

}  // namespace
}  // namespace costume
