#include "haptic_server/grab_forces.h"

#include <gtest/gtest.h>

#include <cmath>

namespace costume::haptics {
namespace {

TEST(GaussianWeight, IsOneAtTheCentre) {
  const Eigen::Vector3d m(0.1, -0.2, 0.3);
  EXPECT_DOUBLE_EQ(GaussianWeight(m, m, GaussianVariance(0.1)), 1.0);
}

TEST(GaussianWeight, IsExpMinusHalfOneStandardDeviationAway) {
  // r = 0.1 m: s = (r/2)² = 0.0025 m², √s = 0.05 m; the point (0.03, 0.04, 0) is 0.05 m away.
  const double s = GaussianVariance(0.1);
  EXPECT_DOUBLE_EQ(s, 0.0025);
  const double g = GaussianWeight(Eigen::Vector3d(0.03, 0.04, 0.0), Eigen::Vector3d::Zero(), s);
  EXPECT_NEAR(g, 0.60653065971263342, 1e-15);  // exp(−1/2)
}

TEST(GaussianWeight, IsExpMinusTwoAtTheRim) {
  // ‖x − m‖ = r = 2√s: g = exp(−4s / 2s) = exp(−2).
  const double g = GaussianWeight(Eigen::Vector3d(0, 0, 0.2), Eigen::Vector3d::Zero(),
                                  GaussianVariance(0.2));
  EXPECT_NEAR(g, 0.1353352832366127, 1e-15);
}

TEST(SelectParticles, KeepsThoseWithinTheRadiusInclusive) {
  sim::Points x(5, 3);
  x << 0, 0, 0,      // centre
      0.05, 0, 0,    // inside
      0, 0.125, 0,   // on the sphere (0.125 is exact in binary)
      0, 0, 0.126,   // just outside
      1, 1, 1;       // far
  std::vector<int> selected;
  SelectParticles(x, Eigen::Vector3d::Zero(), 0.125, selected);
  EXPECT_EQ(selected, (std::vector<int>{0, 1, 2}));
}

TEST(AddGrabForces, AddsTheDeviceForceTimesTheWeight) {
  sim::Points x(3, 3);
  x << 0, 0, 0,  0.03, 0.04, 0,  0.5, 0, 0;
  sim::Points f = sim::Points::Zero(3, 3);
  f(2, 0) = 7.0;  // untouched: not selected
  const Eigen::Vector3d fh(1.0, -2.0, 0.5);
  AddGrabForces(x, {0, 1}, Eigen::Vector3d::Zero(), 0.1, fh, f);
  const double g1 = 0.60653065971263342;  // exp(−1/2): 0.05 m away, s = 0.0025 m²
  EXPECT_NEAR(f(0, 0), 1.0, 1e-15);
  EXPECT_NEAR(f(0, 1), -2.0, 1e-15);
  EXPECT_NEAR(f(1, 0), g1 * 1.0, 1e-15);
  EXPECT_NEAR(f(1, 1), g1 * -2.0, 1e-15);
  EXPECT_NEAR(f(1, 2), g1 * 0.5, 1e-15);
  EXPECT_EQ(f(2, 0), 7.0);
}

// Particles 0 = (0,0,0) and 2 = (0.3,0,0) are inside the sphere (centre 0, r = 0.35 m);
// particle 1 = (0.3,0.4,0) is 0.5 m away, outside.
HapticPatch ThreeParticlePatch() {
  HapticPatch patch;
  patch.sequence = 1;
  patch.centre = Eigen::Vector3d::Zero();
  patch.radius = 0.35;
  patch.positions = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.3, 0.4, 0),
                     Eigen::Vector3d(0.3, 0, 0)};
  patch.velocities = {Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0.5, 0),
                      Eigen::Vector3d(0.1, 0, 0)};
  patch.springs = {
      {0, 1, 10.0, 0.0, 0.4},  // length 0.5, stretched 0.1, direction (0.6, 0.8, 0)
      {2, 1, 20.0, 3.0, 0.3},  // length 0.4, stretched 0.1, direction (0, 1, 0), closing 0.5 m/s
      {0, 2, 50.0, 4.0, 0.2},  // internal: both ends selected, cancels
  };
  PreparePatch(patch);
  return patch;
}

TEST(FeedbackForce, EqualsTheHandComputedSpringForcesOnTheSelectedParticles) {
  const HapticPatch patch = ThreeParticlePatch();
  ASSERT_TRUE(patch.valid);
  EXPECT_EQ(patch.num_selected, 2);
  // On 0 from spring (0,1): 10 · 0.1 · (0.6, 0.8, 0)             = (0.6, 0.8, 0)
  // On 2 from spring (2,1): 20 · 0.1 · (0, 1, 0) + 3 · 0.5 · (0,1,0) = (0, 3.5, 0)
  // Spring (0,2) adds equal and opposite forces to 0 and 2: nothing.
  const Eigen::Vector3d f = FeedbackForce(patch, Eigen::Vector3d::Zero());
  EXPECT_NEAR(f.x(), 0.6, 1e-12);
  EXPECT_NEAR(f.y(), 4.3, 1e-12);
  EXPECT_NEAR(f.z(), 0.0, 1e-12);
  EXPECT_EQ(patch.boundary_springs.size(), 2u);
}

TEST(FeedbackForce, VanishesAtRestLengths) {
  HapticPatch patch = ThreeParticlePatch();
  for (PatchSpring& s : patch.springs) {
    s.rest_length = (patch.positions[s.b] - patch.positions[s.a]).norm();
  }
  for (Eigen::Vector3d& v : patch.velocities) v.setZero();
  PreparePatch(patch);
  EXPECT_LT(FeedbackForce(patch, Eigen::Vector3d::Zero()).norm(), 1e-14);
}

TEST(FeedbackForce, PullsTheHandBackWhenItPullsTheCloth) {
  // One selected particle at the centre tied by a spring at rest to an outside particle in +x.
  HapticPatch patch;
  patch.sequence = 1;
  patch.radius = 0.05;
  patch.positions = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.2, 0, 0)};
  patch.velocities = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  patch.springs = {{0, 1, 100.0, 0.0, 0.2}};
  PreparePatch(patch);
  // The hand moves 1 cm in −x and drags the particle (weight 1 at the centre) with it: the
  // spring stretches by 0.01 m and pulls back with 100 · 0.01 = 1 N in +x.
  const Eigen::Vector3d u(-0.01, 0, 0);
  const Eigen::Vector3d f = FeedbackForce(patch, u);
  EXPECT_NEAR(f.x(), 1.0, 1e-12);
  EXPECT_NEAR(f.y(), 0.0, 1e-15);
  EXPECT_LT(f.dot(u), 0.0);
}

TEST(PreparePatch, MarksANonFinitePatchInvalidAndItRendersNothing) {
  HapticPatch patch = ThreeParticlePatch();
  patch.positions[1].x() = std::nan("");
  PreparePatch(patch);
  EXPECT_FALSE(patch.valid);
  EXPECT_EQ(FeedbackForce(patch, Eigen::Vector3d::Zero()), Eigen::Vector3d::Zero());
}

TEST(PreparePatch, MarksAnOutOfRangeSpringInvalid) {
  HapticPatch patch = ThreeParticlePatch();
  patch.springs.push_back({0, 3, 1.0, 0.0, 1.0});
  PreparePatch(patch);
  EXPECT_FALSE(patch.valid);
}

}  // namespace
}  // namespace costume::haptics
