// The accurate (mesh) avatar collision: contacts and projection against a skinned box with
// hand-computed normals and target velocities, and adaptive regions checked against fixed
// regions and against brute force over all triangles.
#include "sim_core/collision/mesh_collider.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>

#include "sim_core/avatar/skeleton.h"
#include "sim_core/common/input_error.h"
#include "sim_core/collision/mesh_distance.h"
#include "sim_core/collision/surface_geometry.h"
#include "tests/sim_core/collision/test_meshes.h"

#include "tests/support/contact_rule.h"
#include "tests/support/count_mallocs.h"

namespace costume::sim {
namespace {

using test::TestMesh;

constexpr double kH = 1.0 / 60.0;
const Eigen::Vector3d kCenter(0.0, 1.0, 0.0);
const Eigen::Vector3d kHalf(0.2, 0.2, 0.2);

using test::RigidAvatar;

const std::vector<Eigen::Isometry3d> kJoints = {Eigen::Isometry3d::Identity()};

Points Row(const Eigen::Vector3d& v) { return v.transpose(); }

TEST(MeshCollider, ParticleInsideGetsAnOutwardContactAndProjectsOntoTheShell) {
  const auto box = test::TessellatedBox(kCenter, kHalf, Eigen::Vector3i(6, 6, 6));
  BodyCollisionSettings settings;
  settings.thickness = 0.004;
  settings.friction = 0.3;
  MeshCollider collider(RigidAvatar(box), settings);
  collider.Update(kJoints, box.vertices, kH);
  // 1 cm below the top face, off its grid lines.
  Points x = Row(kCenter + Eigen::Vector3d(0.013, kHalf.y() - 0.01, 0.027));
  Points v = Row(Eigen::Vector3d(0.2, -1.0, 0.5));
  std::vector<Contact> contacts;
  collider.FindContacts(x, v, kH, 0.002, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_EQ(contacts[0].particle, 0);
  EXPECT_LT((contacts[0].normal - Eigen::Vector3d::UnitY()).norm(), 1e-12);
  EXPECT_NEAR(contacts[0].target_normal_velocity, (0.004 + 0.01) / kH, 1e-9);
  EXPECT_EQ(contacts[0].friction, 0.3);
  EXPECT_EQ(collider.stats().num_contacts, 1);
  EXPECT_GT(collider.stats().num_tests, 0);

  const double deepest = collider.ProjectOut(x, v);
  EXPECT_NEAR(deepest, 0.014, 1e-12);
  const Eigen::Vector3d moved = x.row(0).transpose();
  EXPECT_NEAR(test::BoxSignedDistance(moved, kCenter, kHalf), 0.004, 1e-6);
  EXPECT_NEAR(moved.x(), 0.013, 1e-12);  // moved along the normal only
  // The inward normal velocity is gone, the tangential one kept.
  EXPECT_NEAR(v(0, 0), 0.2, 1e-12);
  EXPECT_NEAR(v(0, 1), 0.0, 1e-12);
  EXPECT_NEAR(v(0, 2), 0.5, 1e-12);
  EXPECT_EQ(collider.ProjectOut(x, v), 0.0);  // already on the shell
}

// The listed correction moves only the listed particles, each onto the shell as the full one
// does: 1 cm below the top face is 1.4 cm below the 4 mm shell.
TEST(MeshCollider, ListedProjectOutMovesOnlyTheListedParticlesOntoTheShell) {
  const auto box = test::TessellatedBox(kCenter, kHalf, Eigen::Vector3i(6, 6, 6));
  BodyCollisionSettings settings;
  settings.thickness = 0.004;
  MeshCollider collider(RigidAvatar(box), settings);
  collider.Update(kJoints, box.vertices, kH);
  Points x(2, 3);
  x.row(0) = (kCenter + Eigen::Vector3d(0.013, kHalf.y() - 0.01, 0.027)).transpose();
  x.row(1) = (kCenter + Eigen::Vector3d(-0.031, kHalf.y() - 0.01, 0.011)).transpose();
  Points v = Points::Zero(2, 3);
  v.col(1).setConstant(-1.0);
  std::vector<Contact> contacts;
  collider.FindContacts(x, v, kH, 0.002, contacts);
  const Points before = x;
  const std::vector<int> listed = {1};
  EXPECT_NEAR(collider.ProjectOut(x, v, listed), 0.014, 1e-12);
  EXPECT_EQ(x.row(0), before.row(0));
  EXPECT_EQ(v(0, 1), -1.0);
  EXPECT_NEAR(test::BoxSignedDistance(x.row(1).transpose(), kCenter, kHalf), 0.004, 1e-6);
  EXPECT_NEAR(v(1, 1), 0.0, 1e-12);
}

TEST(MeshCollider, ParticleFarOutsideGetsNoneUnlessItWouldArrive) {
  const auto box = test::TessellatedBox(kCenter, kHalf, Eigen::Vector3i(6, 6, 6));
  MeshCollider collider(RigidAvatar(box), BodyCollisionSettings{});
  collider.Update(kJoints, box.vertices, kH);
  std::vector<Contact> contacts;
  collider.FindContacts(Row(kCenter + Eigen::Vector3d(0, 1.0, 0)), Row(Eigen::Vector3d::Zero()),
                        kH, 0.002, contacts);
  EXPECT_TRUE(contacts.empty());
  // 3 cm above the top face: at rest no contact; falling at 3 m/s it would cross the
  // shell within the step (5 cm of travel), so it gets one.
  const Points x = Row(kCenter + Eigen::Vector3d(0.05, kHalf.y() + 0.03, -0.04));
  collider.FindContacts(x, Row(Eigen::Vector3d::Zero()), kH, 0.002, contacts);
  EXPECT_TRUE(contacts.empty());
  collider.FindContacts(x, Row(Eigen::Vector3d(0, -3.0, 0)), kH, 0.002, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR(contacts[0].target_normal_velocity, (0.004 - 0.03) / kH, 1e-9);
}

TEST(MeshCollider, MovingBodyAddsItsVelocityToTheTarget) {
  const auto box = test::TessellatedBox(kCenter, kHalf, Eigen::Vector3i(6, 6, 6));
  MeshCollider collider(RigidAvatar(box), BodyCollisionSettings{});
  const double dt = 0.01;
  const Eigen::Vector3d body_velocity(0.5, 1.0, -0.3);
  collider.Update(kJoints, box.vertices, dt);
  const Eigen::Vector3d moved_center = kCenter + dt * body_velocity;
  collider.Update(kJoints, test::Translated(box, dt * body_velocity).vertices, dt);
  // 1 cm inside below the top face and 2 cm inside behind the +x face.
  Points x(2, 3);
  x.row(0) = (moved_center + Eigen::Vector3d(0.013, kHalf.y() - 0.01, 0.027)).transpose();
  x.row(1) = (moved_center + Eigen::Vector3d(kHalf.x() - 0.02, -0.031, 0.018)).transpose();
  std::vector<Contact> contacts;
  collider.FindContacts(x, Points::Zero(2, 3), kH, 0.002, contacts);
  ASSERT_EQ(contacts.size(), 2u);
  EXPECT_LT((contacts[0].normal - Eigen::Vector3d::UnitY()).norm(), 1e-12);
  EXPECT_NEAR(contacts[0].target_normal_velocity, 1.0 + (0.004 + 0.01) / kH, 1e-9);
  EXPECT_LT((contacts[1].normal - Eigen::Vector3d::UnitX()).norm(), 1e-12);
  EXPECT_NEAR(contacts[1].target_normal_velocity, 0.5 + (0.004 + 0.02) / kH, 1e-9);
  // Projection removes the velocity into the body relative to the body: a particle at
  // rest inside the rising top face ends rising with it.
  Points v = Points::Zero(2, 3);
  collider.ProjectOut(x, v);
  EXPECT_NEAR(v(0, 1), 1.0, 1e-12);
  EXPECT_NEAR(v(1, 0), 0.5, 1e-12);
}

// ---- adaptive regions against fixed regions and brute force --------------------------

// A 1 m × 1 m slab whose top is tessellated finely and gently waved, so it is flat in
// places and merges into large regions.
TestMesh WavySlab() {
  TestMesh slab = test::TessellatedBox(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.5, 0.05, 0.5),
                                       Eigen::Vector3i(32, 2, 32));
  for (Eigen::Index i = 0; i < slab.vertices.rows(); ++i) {
    if (slab.vertices(i, 1) > 0.049) {
      slab.vertices(i, 1) += 0.01 * std::sin(3.0 * slab.vertices(i, 0)) *
                             std::cos(2.0 * slab.vertices(i, 2));
    }
  }
  return slab;
}

// Brute force over all triangles, written apart from the collider: the closest point by
// projection onto the plane or else onto the three edges.
Eigen::Vector3d ClosestOnSegment(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                 const Eigen::Vector3d& b) {
  const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
  return a + t * (b - a);
}

Eigen::Vector3d ClosestOnTriangleBrute(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
  const Eigen::Vector3d q = p - n * (p - a).dot(n);
  const bool inside = (b - a).cross(q - a).dot(n) >= 0 && (c - b).cross(q - b).dot(n) >= 0 &&
                      (a - c).cross(q - c).dot(n) >= 0;
  if (inside) return q;
  Eigen::Vector3d best = ClosestOnSegment(p, a, b);
  for (const Eigen::Vector3d& e : {ClosestOnSegment(p, b, c), ClosestOnSegment(p, c, a)}) {
    if ((p - e).squaredNorm() < (p - best).squaredNorm()) best = e;
  }
  return best;
}

struct BruteContact {
  int particle;
  Eigen::Vector3d normal;
  double target;
};

// Contacts of the collider's rule, from the nearest of all triangles. The sign uses the
// nearest triangle's face normal: right here, where particles stay well inside the slab's
// gently curved top and away from its rim.
std::vector<BruteContact> BruteForceContacts(const TestMesh& mesh, const Points& x,
                                             const Points& v, const Eigen::Vector3d& body_velocity,
                                             double thickness, double margin) {
  std::vector<BruteContact> contacts;
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    const Eigen::Vector3d p = x.row(i).transpose();
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector3d closest = Eigen::Vector3d::Zero(), face = Eigen::Vector3d::UnitY();
    for (const Eigen::Vector3i& t : mesh.triangles) {
      const Eigen::Vector3d a = mesh.vertices.row(t[0]), b = mesh.vertices.row(t[1]),
                            c = mesh.vertices.row(t[2]);
      const Eigen::Vector3d q = ClosestOnTriangleBrute(p, a, b, c);
      if ((p - q).squaredNorm() < best) {
        best = (p - q).squaredNorm();
        closest = q;
        face = (b - a).cross(c - a).normalized();
      }
    }
    const double distance = std::sqrt(best);
    const double sign = (p - closest).dot(face) < 0.0 ? -1.0 : 1.0;
    const Eigen::Vector3d normal = sign * (p - closest) / distance;
    const double d = sign * distance;
    const double relative = (v.row(i).transpose() - body_velocity).dot(normal);
    if (d >= thickness && d + kH * relative > thickness + margin) continue;
    contacts.push_back({static_cast<int>(i), normal,
                        costume::test::ExpectedContactVelocity(body_velocity.dot(normal), d - thickness,
                                                      relative, kH)});
  }
  return contacts;
}

void ExpectSameContacts(const std::vector<Contact>& got, const std::vector<BruteContact>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    ASSERT_EQ(got[k].particle, want[k].particle);
    EXPECT_LT((got[k].normal - want[k].normal).norm(), 1e-9) << got[k].particle;
    EXPECT_NEAR(got[k].target_normal_velocity, want[k].target, 1e-7) << got[k].particle;
  }
}

TEST(MeshCollider, AdaptiveRegionsTestLessAndFindTheSameContactsAsFixedAndBruteForce) {
  const TestMesh slab = WavySlab();
  const auto avatar = RigidAvatar(slab);
  BodyCollisionSettings settings;
  MeshCollisionOptions adaptive_options;
  adaptive_options.max_penetration = 0.02;
  MeshCollisionOptions fixed_options = adaptive_options;
  fixed_options.adaptive = false;
  MeshCollider adaptive(avatar, settings, adaptive_options);
  MeshCollider fixed(avatar, settings, fixed_options);
  EXPECT_EQ(adaptive.num_base_regions(), fixed.num_regions());
  EXPECT_LT(adaptive.num_regions(), fixed.num_regions());

  // The slab moves: surface velocities enter the targets.
  const double dt = kH;
  const Eigen::Vector3d body_velocity(0.1, 0.3, -0.2);
  const TestMesh moved = test::Translated(slab, dt * body_velocity);
  for (MeshCollider* collider : {&adaptive, &fixed}) {
    collider->Update(kJoints, slab.vertices, dt);
    collider->Update(kJoints, moved.vertices, dt);
  }
  // Particles over the top, from 1 cm below it to 3 cm above, moving up to 0.5 m/s.
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> across(-0.45, 0.45), height(-0.01, 0.03),
      speed(-0.3, 0.3);
  const int n = 1500;
  Points x(n, 3), v(n, 3);
  for (int i = 0; i < n; ++i) {
    const double px = across(rng), pz = across(rng);
    const double top = 0.05 + 0.01 * std::sin(3.0 * px) * std::cos(2.0 * pz);
    x.row(i) = (dt * body_velocity + Eigen::Vector3d(px, top + height(rng), pz)).transpose();
    v.row(i) = Eigen::Vector3d(speed(rng), speed(rng), speed(rng)).transpose();
  }
  const double margin = 0.003;
  std::vector<Contact> from_adaptive, from_fixed;
  adaptive.FindContacts(x, v, kH, margin, from_adaptive);
  fixed.FindContacts(x, v, kH, margin, from_fixed);
  const auto brute = BruteForceContacts(moved, x, v, body_velocity, settings.thickness, margin);
  ASSERT_GT(brute.size(), 200u);
  ASSERT_LT(brute.size(), static_cast<std::size_t>(n) - 200);  // both cases present
  ExpectSameContacts(from_adaptive, brute);
  ExpectSameContacts(from_fixed, brute);
  EXPECT_LT(adaptive.stats().num_tests, fixed.stats().num_tests);
  std::printf("regions %d adaptive / %d fixed; tests %lld adaptive / %lld fixed (%.1f%% fewer)\n",
              adaptive.num_regions(), fixed.num_regions(), adaptive.stats().num_tests,
              fixed.stats().num_tests,
              100.0 * (1.0 - double(adaptive.stats().num_tests) / fixed.stats().num_tests));
}

TEST(MeshCollider, CurvedBodyGivesTheSameContactsAdaptiveOrFixed) {
  const TestMesh sphere = test::CubeSphere(kCenter, 0.25, 12);
  const auto avatar = RigidAvatar(sphere);
  MeshCollisionOptions fixed_options;
  fixed_options.adaptive = false;
  MeshCollider adaptive(avatar, BodyCollisionSettings{});
  MeshCollider fixed(avatar, BodyCollisionSettings{}, fixed_options);
  std::mt19937 rng(23);
  std::normal_distribution<double> gauss;
  std::uniform_real_distribution<double> radial(0.22, 0.29), speed(-1.0, 1.0);
  const int n = 1000;
  Points x(n, 3), v(n, 3);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d direction =
        Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    x.row(i) = (kCenter + radial(rng) * direction).transpose();
    v.row(i) = Eigen::Vector3d(speed(rng), speed(rng), speed(rng)).transpose();
  }
  std::vector<Contact> a, b;
  adaptive.FindContacts(x, v, kH, 0.003, a);
  fixed.FindContacts(x, v, kH, 0.003, b);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 100u);
  std::printf("curved: regions %d adaptive / %d fixed; tests %lld adaptive / %lld fixed\n",
              adaptive.num_regions(), fixed.num_regions(), adaptive.stats().num_tests,
              fixed.stats().num_tests);
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a[k].particle, b[k].particle);
    EXPECT_LT((a[k].normal - b[k].normal).norm(), 1e-12);
    EXPECT_NEAR(a[k].target_normal_velocity, b[k].target_normal_velocity, 1e-9);
    // Outward: the normal points away from the centre.
    EXPECT_GT(a[k].normal.dot(x.row(a[k].particle).transpose() - kCenter), 0.0);
  }
}

// Two overlapping boxes as two pieces: the body is their union. Their closed form gives
// each particle's expected contact: per box the exact signed distance and its gradient
// (the direction from the closest surface point, or inside the nearest face's normal);
// the box with the smaller signed distance wins.
struct BoxContact {
  double distance;
  Eigen::Vector3d normal;
};

BoxContact ClosedFormBoxContact(const Eigen::Vector3d& p, const Eigen::Vector3d& center,
                                const Eigen::Vector3d& half) {
  const double d = test::BoxSignedDistance(p, center, half);
  const Eigen::Vector3d local = p - center;
  if (d > 0.0) {
    const Eigen::Vector3d closest = center + local.cwiseMax(-half).cwiseMin(half);
    return {d, (p - closest) / d};
  }
  Eigen::Index axis = 0;
  (local.cwiseAbs() - half).maxCoeff(&axis);
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  normal[axis] = local[axis] < 0.0 ? -1.0 : 1.0;
  return {d, normal};
}

/// One body of two meshes' vertices and triangles (two pieces).
TestMesh BothMeshes(const TestMesh& a, const TestMesh& b) {
  TestMesh both;
  both.vertices.resize(a.vertices.rows() + b.vertices.rows(), 3);
  both.vertices << a.vertices, b.vertices;
  both.triangles = a.triangles;
  for (const Eigen::Vector3i& t : b.triangles) {
    both.triangles.push_back(t + Eigen::Vector3i::Constant(static_cast<int>(a.vertices.rows())));
  }
  return both;
}

TEST(MeshCollider, EachParticleGetsItsNearestOrDeepestTriangleOnTwoOverlappingBoxes) {
  const Eigen::Vector3d center_a(0.0, 1.0, 0.0), half_a(0.15, 0.1, 0.12);
  const Eigen::Vector3d center_b(0.12, 1.05, 0.04), half_b(0.08, 0.12, 0.1);
  const TestMesh a = test::TessellatedBox(center_a, half_a, Eigen::Vector3i(9, 6, 7));
  const TestMesh b = test::TessellatedBox(center_b, half_b, Eigen::Vector3i(5, 7, 6));
  const TestMesh both = BothMeshes(a, b);
  // Particles from 4 cm inside either box (within max_penetration, so the search reaches
  // both boxes' surfaces) to 5 cm outside the union, near faces, edges and corners alike,
  // moving at up to 1 m/s.
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> across(-0.25, 0.28), speed(-1.0, 1.0);
  const int n = 3000;
  Points x(n, 3), v(n, 3);
  std::vector<BoxContact> truth;
  for (int i = 0; i < n;) {
    const Eigen::Vector3d p = Eigen::Vector3d(0.0, 1.02, 0.02) +
                              Eigen::Vector3d(across(rng), across(rng), across(rng));
    const BoxContact in_a = ClosedFormBoxContact(p, center_a, half_a);
    const BoxContact in_b = ClosedFormBoxContact(p, center_b, half_b);
    if (in_a.distance < -0.04 || in_b.distance < -0.04) continue;
    const BoxContact& nearest = in_a.distance < in_b.distance ? in_a : in_b;
    if (nearest.distance > 0.05) continue;
    x.row(i) = p.transpose();
    v.row(i) = Eigen::Vector3d(speed(rng), speed(rng), speed(rng)).transpose();
    truth.push_back(nearest);
    ++i;
  }
  BodyCollisionSettings settings;
  const double margin = 0.003;
  for (bool adaptive : {true, false}) {
    MeshCollisionOptions options;
    options.adaptive = adaptive;
    MeshCollider collider(RigidAvatar(both), settings, options);
    collider.Update(kJoints, both.vertices, kH);  // at rest
    std::vector<Contact> contacts;
    collider.FindContacts(x, v, kH, margin, contacts);
    std::size_t k = 0;
    int num_inside = 0;
    for (int i = 0; i < n; ++i) {
      const double d = truth[i].distance;
      const Eigen::Vector3d& normal = truth[i].normal;
      num_inside += d < 0.0 ? 1 : 0;
      const bool expected =
          d < settings.thickness ||
          d + kH * v.row(i).dot(normal) <= settings.thickness + margin;
      const bool got = k < contacts.size() && contacts[k].particle == i;
      ASSERT_EQ(got, expected) << "particle " << i << " at distance " << d;
      if (!got) continue;
      EXPECT_LT((contacts[k].normal - normal).norm(), 1e-9) << i;
      EXPECT_NEAR(contacts[k].target_normal_velocity,
                  costume::test::ExpectedContactVelocity(0.0, d - settings.thickness,
                                                v.row(i).dot(normal), kH),
                  1e-7)
          << i;
      ++k;
    }
    EXPECT_EQ(k, contacts.size());
    EXPECT_GT(num_inside, 300);
    // The correction moves each particle inside the shell by thickness − d along its normal,
    // and, if that leaves it inside the other box's shell, again out of that one (up to
    // kMeshProjectionPasses times); the reported depth is the first pass's.
    Points moved = x, moved_v = Points::Zero(n, 3);
    double deepest = 0.0;
    for (int i = 0; i < n; ++i) deepest = std::max(deepest, settings.thickness - truth[i].distance);
    EXPECT_NEAR(collider.ProjectOut(moved, moved_v), deepest, 1e-12);
    int twice = 0;
    for (int i = 0; i < n; ++i) {
      Eigen::Vector3d want = x.row(i).transpose();
      for (int pass = 0; pass < kMeshProjectionPasses; ++pass) {
        const BoxContact in_a = ClosedFormBoxContact(want, center_a, half_a);
        const BoxContact in_b = ClosedFormBoxContact(want, center_b, half_b);
        const BoxContact& nearest = in_a.distance < in_b.distance ? in_a : in_b;
        if (nearest.distance >= settings.thickness) break;
        twice += pass == 1 ? 1 : 0;
        want += (settings.thickness - nearest.distance) * nearest.normal;
      }
      EXPECT_LT((moved.row(i).transpose() - want).norm(), 1e-9) << i;
    }
    EXPECT_GT(twice, 0);  // the second pass was exercised
  }
}

// Two boxes face each other across a gap of 2 mm, narrower than two 4 mm shells, as an arm
// swung against the torso leaves the armpit. A particle 2 mm inside one box goes midway,
// 1 mm outside each (the closed-form box distances as oracle), with no velocity into either.
// Pushed out of one box onto its shell, it would be 2 mm inside the other, and pushed out of
// that one as deep into the first: MakeHuman's suit walking with multigrid ended 3.60 mm
// inside the skin at the left armpit so (docs/collision.md, "Pinches").
TEST(MeshCollider, ParticleInAPinchNarrowerThanTwoShellsGoesMidway) {
  const Eigen::Vector3d half(0.1, 0.2, 0.2);
  const Eigen::Vector3d center_a(-0.101, 1.0, 0.0), center_b(0.101, 1.0, 0.0);
  const TestMesh a = test::TessellatedBox(center_a, half, Eigen::Vector3i(5, 8, 8));
  const TestMesh b = test::TessellatedBox(center_b, half, Eigen::Vector3i(5, 8, 8));
  const TestMesh both = BothMeshes(a, b);
  BodyCollisionSettings settings;
  settings.thickness = 0.004;
  MeshCollider collider(RigidAvatar(both), settings);
  collider.Update(kJoints, both.vertices, kH);
  const Eigen::Vector3d start(-0.003, 1.013, 0.027);
  ASSERT_NEAR(test::BoxSignedDistance(start, center_a, half), -0.002, 1e-12);
  Points x = Row(start);
  Points v = Row(Eigen::Vector3d(0.3, 0.1, 0.0));
  collider.ProjectOut(x, v);
  const Eigen::Vector3d moved = x.row(0).transpose();
  EXPECT_NEAR(test::BoxSignedDistance(moved, center_a, half), 0.001, 1e-9);
  EXPECT_NEAR(test::BoxSignedDistance(moved, center_b, half), 0.001, 1e-9);
  EXPECT_NEAR(moved.y(), start.y(), 1e-12);
  EXPECT_NEAR(moved.z(), start.z(), 1e-12);
  EXPECT_NEAR(v(0, 0), 0.0, 1e-12);  // not into box b (nor, outward, into a)
  EXPECT_NEAR(v(0, 1), 0.1, 1e-12);
}

/// `bar` (a box along x from 0, its axis at y = 1) with its far half, x > `middle`, turned
/// 90° about the z axis through (middle, 1.0), as skinning turns a thigh: that half then
/// stands up through the near half's top face, which it buries.
TestMesh FoldedAtTheMiddle(const TestMesh& bar, double middle) {
  TestMesh folded = bar;
  for (Eigen::Index v = 0; v < folded.vertices.rows(); ++v) {
    const double dx = bar.vertices(v, 0) - middle, dy = bar.vertices(v, 1) - 1.0;
    if (dx > 1e-9) folded.vertices.row(v) << middle - dy, 1.0 + dx, bar.vertices(v, 2);
  }
  return folded;
}

// A bar 20 cm long along x, its far half turned 90° about the z axis through the middle of
// its axis, as skinning turns a thigh: the far half (now x in [0.05, 0.15], y in [1.01,
// 1.1]) runs through the near half's top face (y = 1.05), which is buried in it for x in
// [0.05, 0.1]. One piece, closed. The particle 5 mm above that buried face is inside the
// far half; its nearest skin is the buried face, seen from its outer side.
TEST(MeshCollider, ParticleInSkinThatBuriedItsNearestSkinIsMovedOutThroughIt) {
  const Eigen::Vector3d half(0.1, 0.05, 0.05);
  const TestMesh bar =
      test::TessellatedBox(Eigen::Vector3d(half.x(), 1.0, 0.0), half, Eigen::Vector3i(20, 10, 10));
  const TestMesh folded = FoldedAtTheMiddle(bar, half.x());
  const Eigen::Vector3d buried(0.075, 1.055, 0.003);
  const Eigen::Vector3d outside(0.04, 1.065, 0.003);  // in the corner the fold leaves open
  // The setup, by an independent oracle: inside by the winding number, 5 mm outside its
  // nearest triangle's pseudonormal.
  const MeshDistance oracle("folded bar", folded.vertices, folded.triangles);
  ASSERT_TRUE(oracle.Inside(buried));
  ASSERT_NEAR(oracle.SignedDistance(buried, 0.1), 0.005, 1e-9);
  ASSERT_FALSE(oracle.Inside(outside));

  for (const bool find_buried : {false, true}) {
    SCOPED_TRACE(find_buried ? "find_buried" : "without find_buried");
    MeshCollisionOptions options;
    options.find_buried = find_buried;
    BodyCollisionSettings settings;
    settings.thickness = 0.004;
    MeshCollider collider(RigidAvatar(bar), settings, options);
    collider.Update(kJoints, folded.vertices, kH);  // the first pose: the body at rest
    Points x(2, 3), v(2, 3);
    x << buried.transpose(), outside.transpose();
    v << 0.5, 0.2, 0.0, 0.5, 0.2, 0.0;  // the first into the far half's face x = 0.05
    const double deepest = collider.ProjectOut(x, v);
    EXPECT_EQ((x.row(1).transpose() - outside).norm(), 0.0);
    EXPECT_EQ(v(1, 0), 0.5);
    if (!find_buried) {
      EXPECT_EQ((x.row(0).transpose() - buried).norm(), 0.0);  // left buried
      EXPECT_EQ(deepest, 0.0);
      continue;
    }
    // Out through the far half's face x = 0.05, 25 mm away, onto the shell 4 mm beyond it
    // (the rays are turned off the axes by under a milliradian). Nearer skin it lies
    // behind, the twisted band at the fold 19.5 mm away, leads into the near half.
    EXPECT_NEAR(deepest, 0.025 + 0.004, 1e-7);
    EXPECT_LT((x.row(0).transpose() - Eigen::Vector3d(0.046, 1.055, 0.003)).norm(), 1e-4);
    EXPECT_FALSE(oracle.Inside(x.row(0).transpose()));
    EXPECT_NEAR(oracle.SignedDistance(x.row(0).transpose(), 0.1), 0.004, 1e-7);
    EXPECT_NEAR(v(0, 0), 0.0, 1e-12);  // the velocity into the body is gone
    EXPECT_NEAR(v(0, 1), 0.2, 1e-12);
    EXPECT_EQ(collider.stats().num_buried, 1);
    EXPECT_EQ(collider.stats().num_winding_checks, 2);
  }

  // Points all over the far half above the buried face: with find_buried every one ends
  // outside by the oracle; without it, those nearer the buried face than to the far
  // half's own faces stay in.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> across_x(0.052, 0.098), across_y(1.052, 1.098),
      across_z(-0.045, 0.045);
  Points points(200, 3);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    points.row(i) << across_x(rng), across_y(rng), across_z(rng);
  }
  for (const bool find_buried : {false, true}) {
    MeshCollisionOptions options;
    options.find_buried = find_buried;
    MeshCollider collider(RigidAvatar(bar), BodyCollisionSettings{}, options);
    collider.Update(kJoints, folded.vertices, kH);
    Points x = points, v = Points::Zero(points.rows(), 3);
    collider.ProjectOut(x, v);
    int inside = 0;
    for (Eigen::Index i = 0; i < x.rows(); ++i) inside += oracle.Inside(x.row(i).transpose());
    if (find_buried) {
      EXPECT_EQ(inside, 0);
    } else {
      EXPECT_GT(inside, 20);
    }
  }
}

// The same fold in a bar twice as thick (40 × 20 × 20 cm, folded about (0.2, 1.0)): the
// far half now spans x in [0.1, 0.3], y in [1.0, 1.2], and buries the near half's top
// face (y = 1.1) for x in [0.1, 0.2]. A particle 5 mm above that face, 60 mm from the far
// half's face x = 0.1, has no exit within max_penetration (5 cm): inside the piece whose
// own nearest skin puts it outside, the piece is folded through itself and exits are
// looked for up to 30 cm away (as a raised thigh skinned into the belly needs).
TEST(MeshCollider, ParticleBuriedDeeperThanMaxPenetrationInAFoldGoesOutThroughIt) {
  const Eigen::Vector3d half(0.2, 0.1, 0.1);
  const TestMesh bar =
      test::TessellatedBox(Eigen::Vector3d(half.x(), 1.0, 0.0), half, Eigen::Vector3i(40, 20, 20));
  const TestMesh folded = FoldedAtTheMiddle(bar, half.x());
  const Eigen::Vector3d buried(0.16, 1.105, 0.003);
  const MeshDistance oracle("folded thick bar", folded.vertices, folded.triangles);
  ASSERT_TRUE(oracle.Inside(buried));
  ASSERT_NEAR(oracle.SignedDistance(buried, 0.1), 0.005, 1e-9);
  MeshCollisionOptions defaults;
  ASSERT_EQ(defaults.max_penetration, 0.05);

  BodyCollisionSettings settings;
  settings.thickness = 0.004;
  MeshCollider collider(RigidAvatar(bar), settings);
  collider.Update(kJoints, folded.vertices, kH);
  Points x = Row(buried), v = Row(Eigen::Vector3d(0.5, 0.2, 0.0));
  const double deepest = collider.ProjectOut(x, v);
  // Out through x = 0.1, 60 mm away, onto the shell beyond it, above the near half.
  EXPECT_NEAR(deepest, 0.06 + 0.004, 1e-6);
  EXPECT_LT((x.row(0).transpose() - Eigen::Vector3d(0.096, 1.105, 0.003)).norm(), 1e-4);
  EXPECT_FALSE(oracle.Inside(x.row(0).transpose()));
  EXPECT_GE(oracle.SignedDistance(x.row(0).transpose(), 0.1), 0.004 - 1e-6);
  EXPECT_NEAR(v(0, 0), 0.0, 1e-12);  // the velocity into that face is gone
  EXPECT_NEAR(v(0, 1), 0.2, 1e-12);
  EXPECT_EQ(collider.stats().num_buried, 1);
}

// A particle the skin was near at the step's start, found more than max_penetration (5 cm)
// deep after the solve (a kicking leg swept through loose trousers), is beyond any
// proximity search: it goes out along the nearest exit ray, as a buried one does. One
// that left the skin as far outward stays where it is.
TEST(MeshCollider, ParticleDeeperThanMaxPenetrationAfterTheStepIsMovedOut) {
  const auto box = test::TessellatedBox(kCenter, kHalf, Eigen::Vector3i(6, 6, 6));
  const double top = kCenter.y() + kHalf.y();
  BodyCollisionSettings settings;
  settings.thickness = 0.004;
  MeshCollisionOptions defaults;
  ASSERT_EQ(defaults.max_penetration, 0.05);
  const Eigen::Vector3d start(0.013, top + 0.01, 0.027);  // 1 cm above the top face
  for (const bool find_buried : {false, true}) {
    SCOPED_TRACE(find_buried ? "find_buried" : "without find_buried");
    MeshCollisionOptions options;
    options.find_buried = find_buried;
    MeshCollider collider(RigidAvatar(box), settings, options);
    collider.Update(kJoints, box.vertices, kH);
    Points x(2, 3), v(2, 3);
    x << start.transpose(), start.transpose();
    v << 0.0, -4.8, 0.0, 0.0, 4.8, 0.0;  // 8 cm in a step, down and up
    std::vector<Contact> contacts;
    collider.FindContacts(x, v, kH, 0.002, contacts);
    ASSERT_EQ(contacts.size(), 1u);  // the first would cross the shell in the step
    // Where the step took them: 66 mm below the top face (134 mm from every other), and
    // 86 mm above it.
    x.row(0) << 0.013, top - 0.066, 0.027;
    x.row(1) << 0.013, top + 0.086, 0.027;
    const Points outside = x.row(1);
    const double deepest = collider.ProjectOut(x, v);
    EXPECT_EQ((x.row(1) - outside).norm(), 0.0);
    EXPECT_EQ(v(1, 1), 4.8);
    if (!find_buried) {
      EXPECT_NEAR(x(0, 1), top - 0.066, 1e-12);  // lost
      EXPECT_EQ(deepest, 0.0);
      continue;
    }
    // Out through the top face onto the shell (the ray is off the axis by under a
    // milliradian), its velocity into the body gone.
    EXPECT_NEAR(deepest, 0.066 + 0.004, 1e-7);
    EXPECT_LT((x.row(0).transpose() - Eigen::Vector3d(0.013, top + 0.004, 0.027)).norm(), 1e-4);
    EXPECT_NEAR(test::BoxSignedDistance(x.row(0).transpose(), kCenter, kHalf), 0.004, 1e-7);
    EXPECT_NEAR(v(0, 1), 0.0, 1e-12);
    EXPECT_EQ(collider.stats().num_winding_checks, 2);
    EXPECT_EQ(collider.stats().num_buried, 1);
  }
}

// The remembered bounds skip pieces the particle's and the body's motion cannot have
// brought near enough to matter: over a moving, deforming body of three closed pieces and
// particles moving through its shell, the contacts and corrections are those of searching
// every piece every time.
TEST(MeshCollider, RememberedBoundsGiveTheContactsOfAFullSearchOnAMovingBody) {
  const TestMesh a = test::TessellatedBox(Eigen::Vector3d(0.0, 1.0, 0.0),
                                          Eigen::Vector3d(0.15, 0.1, 0.12), Eigen::Vector3i(9, 6, 7));
  const TestMesh b = test::TessellatedBox(Eigen::Vector3d(0.12, 1.05, 0.04),
                                          Eigen::Vector3d(0.08, 0.12, 0.1), Eigen::Vector3i(5, 7, 6));
  const TestMesh c = test::CubeSphere(Eigen::Vector3d(-0.2, 0.95, 0.05), 0.09, 6);
  TestMesh body;
  body.vertices.resize(a.vertices.rows() + b.vertices.rows() + c.vertices.rows(), 3);
  body.vertices << a.vertices, b.vertices, c.vertices;
  body.triangles = a.triangles;
  int offset = static_cast<int>(a.vertices.rows());
  for (const TestMesh* piece : {&b, &c}) {
    for (const Eigen::Vector3i& t : piece->triangles) {
      body.triangles.push_back(t + Eigen::Vector3i::Constant(offset));
    }
    offset += static_cast<int>(piece->vertices.rows());
  }
  MeshCollisionOptions reuse, full;
  full.reuse_bounds = false;
  BodyCollisionSettings settings;
  MeshCollider remembering(RigidAvatar(body), settings, reuse);
  MeshCollider searching(RigidAvatar(body), settings, full);
  // Particles around the body, from inside it to 8 cm out, each on its own straight path.
  std::mt19937 rng(41);
  std::uniform_real_distribution<double> across(-0.35, 0.3), speed(-0.6, 0.6);
  const int n = 1500;
  Points x(n, 3), v(n, 3);
  for (int i = 0; i < n; ++i) {
    x.row(i) = Eigen::RowVector3d(across(rng), 1.0 + across(rng) * 0.6, across(rng) * 0.7);
    v.row(i) = Eigen::RowVector3d(speed(rng), speed(rng), speed(rng));
  }
  long long tests_remembering = 0, tests_searching = 0;
  int num_contacts = 0;
  for (int step = 0; step < 40; ++step) {
    // The body sways, turns and breathes: each piece moves, no piece passes through itself.
    const double t = step * kH;
    const Eigen::Matrix3d turn =
        Eigen::AngleAxisd(0.8 * std::sin(3.0 * t), Eigen::Vector3d::UnitY()).toRotationMatrix();
    const double scale = 1.0 + 0.05 * std::sin(5.0 * t);
    const Eigen::Vector3d shift(0.1 * std::sin(4.0 * t), 0.02 * std::cos(6.0 * t), 0.0);
    Points pose = body.vertices;
    for (Eigen::Index k = 0; k < pose.rows(); ++k) {
      const Eigen::Vector3d rest = body.vertices.row(k).transpose() - Eigen::Vector3d(0, 1, 0);
      pose.row(k) = (scale * (turn * rest) + Eigen::Vector3d(0, 1, 0) + shift).transpose();
    }
    std::vector<Contact> got, want;
    for (MeshCollider* collider : {&remembering, &searching}) collider->Update(kJoints, pose, kH);
    remembering.FindContacts(x, v, kH, 0.003, got);
    searching.FindContacts(x, v, kH, 0.003, want);
    tests_remembering += remembering.stats().num_tests;
    tests_searching += searching.stats().num_tests;
    ASSERT_EQ(got.size(), want.size()) << "step " << step;
    for (std::size_t k = 0; k < got.size(); ++k) {
      ASSERT_EQ(got[k].particle, want[k].particle) << "step " << step;
      EXPECT_LT((got[k].normal - want[k].normal).norm(), 1e-9);
      EXPECT_NEAR(got[k].target_normal_velocity, want[k].target_normal_velocity, 1e-7);
    }
    num_contacts += static_cast<int>(got.size());
    // The particles move on (some into the body), then both correct them.
    x += kH * v;
    Points x_got = x, v_got = v, x_want = x, v_want = v;
    EXPECT_EQ(remembering.ProjectOut(x_got, v_got), searching.ProjectOut(x_want, v_want));
    EXPECT_LT((x_got - x_want).cwiseAbs().maxCoeff(), 1e-12) << "step " << step;
    EXPECT_LT((v_got - v_want).cwiseAbs().maxCoeff(), 1e-12) << "step " << step;
    // Bounce off the box enclosing the scene so that particles keep crossing the shell.
    for (int i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        if (std::abs(x(i, k) - (k == 1 ? 1.0 : 0.0)) > 0.35) v(i, k) = -v(i, k);
      }
    }
  }
  EXPECT_GT(num_contacts, 2000);
  // The memory saves work (it is not a search of everything every time).
  EXPECT_LT(10 * tests_remembering, 7 * tests_searching);
  std::printf("moving body: tests %lld remembering / %lld searching everything\n",
              tests_remembering, tests_searching);
}

TEST(MeshCollider, SkinNoQueryReachedWhileItMovedIsFittedWhereItWentWhenClothComes) {
  // A bar 60 cm long; its right half rises 3 cm a step for ten steps (sheared over
  // 0 <= x <= 0.1) while the only cloth lies on its left end. The right half's regions are
  // then left unfitted (lazy refit), their tree boxes grown by the 30 cm they moved, more
  // than any search reaches (with boxes not grown, the particle below finds no contact). A
  // particle 1 cm inside the risen right half must still be found and put on its shell,
  // where the skinned bar itself (MeshDistance) puts it, as refitting every region every
  // step does.
  const TestMesh bar = test::TessellatedBox(Eigen::Vector3d(0.0, 1.0, 0.0),
                                            Eigen::Vector3d(0.3, 0.05, 0.1),
                                            Eigen::Vector3i(30, 5, 10));
  MeshCollisionOptions lazy, eager;
  lazy.adaptive = eager.adaptive = false;  // the bar's flat faces would merge end to end
  eager.lazy_refit = false;
  BodyCollisionSettings settings;
  MeshCollider lazy_collider(RigidAvatar(bar), settings, lazy);
  MeshCollider eager_collider(RigidAvatar(bar), settings, eager);
  ASSERT_GT(lazy_collider.num_regions(), 4);
  auto pose = [&](int step) {
    Points p = bar.vertices;
    for (Eigen::Index k = 0; k < p.rows(); ++k) {
      p(k, 1) += 0.03 * step * std::clamp(p(k, 0) / 0.1, 0.0, 1.0);
    }
    return p;
  };
  // Cloth resting 2 mm above the left end's top (y = 1.05), in its shell.
  Points rest(5, 3);
  for (int i = 0; i < 5; ++i) rest.row(i) = Eigen::RowVector3d(-0.28 + 0.01 * i, 1.052, 0.0);
  for (int step = 1; step <= 10; ++step) {
    for (MeshCollider* collider : {&lazy_collider, &eager_collider}) {
      collider->Update(kJoints, pose(step), kH);
      Points x = rest, v = Points::Zero(5, 3);
      std::vector<Contact> contacts;
      collider->FindContacts(x, v, kH, 0.002, contacts);
      EXPECT_EQ(contacts.size(), 5u);
      collider->ProjectOut(x, v);
    }
  }
  EXPECT_GT(lazy_collider.num_stale_regions(), 0);
  EXPECT_EQ(eager_collider.num_stale_regions(), 0);
  // The risen top is at y = 1.35 for x >= 0.1.
  MeshDistance skin("bar", pose(10), bar.triangles);
  const Eigen::Vector3d inside(0.25, 1.34, 0.02);
  ASSERT_LT(skin.SignedDistance(inside, 0.2), -0.009);
  Points x_lazy = inside.transpose(), v_lazy = Points::Zero(1, 3);
  Points x_eager = x_lazy, v_eager = v_lazy;
  std::vector<Contact> contacts;
  lazy_collider.FindContacts(x_lazy, v_lazy, kH, 0.002, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_GT(contacts[0].normal.y(), 0.999);
  lazy_collider.ProjectOut(x_lazy, v_lazy);
  eager_collider.ProjectOut(x_eager, v_eager);
  const Eigen::Vector3d out = x_lazy.row(0).transpose();
  EXPECT_NEAR(skin.SignedDistance(out, 0.2), settings.thickness, 1e-6);
  EXPECT_NEAR(out.y(), 1.35 + settings.thickness, 1e-6);
  EXPECT_LT((x_lazy - x_eager).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(MeshCollider, ABodyOfManyPiecesGoesWithoutMemoryAndFindsTheSameContacts) {
  // 80 small closed boxes in a row (more pieces than the memory serves), a particle 2 mm
  // above the middle of each top: each is in contact, with normal +y, twice in a row.
  TestMesh body;
  const int n = 80;
  const Eigen::Vector3d half(0.01, 0.01, 0.01);
  std::vector<Eigen::Vector3d> centers;
  for (int k = 0; k < n; ++k) {
    centers.emplace_back(0.05 * k, 1.0, 0.0);
    const TestMesh box = test::TessellatedBox(centers.back(), half, Eigen::Vector3i(1, 1, 1));
    const int offset = static_cast<int>(body.vertices.rows());
    body.vertices.conservativeResize(offset + box.vertices.rows(), 3);
    body.vertices.bottomRows(box.vertices.rows()) = box.vertices;
    for (const Eigen::Vector3i& t : box.triangles) {
      body.triangles.push_back(t + Eigen::Vector3i::Constant(offset));
    }
  }
  MeshCollider collider(RigidAvatar(body), BodyCollisionSettings{});
  collider.Update(kJoints, body.vertices, kH);
  Points x(n, 3), v = Points::Zero(n, 3);
  for (int k = 0; k < n; ++k) x.row(k) = (centers[k] + Eigen::Vector3d(0.003, 0.012, -0.002)).transpose();
  for (int call = 0; call < 2; ++call) {
    std::vector<Contact> contacts;
    collider.FindContacts(x, v, kH, 0.003, contacts);
    ASSERT_EQ(contacts.size(), static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) {
      EXPECT_EQ(contacts[k].particle, k);
      EXPECT_LT((contacts[k].normal - Eigen::Vector3d::UnitY()).norm(), 1e-12);
      EXPECT_NEAR(contacts[k].target_normal_velocity, (0.004 - 0.002) / kH, 1e-9);
    }
  }
}

TEST(MeshCollider, UpdateFindContactsAndProjectOutDoNotAllocateAfterTheFirstCall) {
  const TestMesh sphere = test::CubeSphere(kCenter, 0.25, 8);
  MeshCollider collider(RigidAvatar(sphere), BodyCollisionSettings{});
  Points x(200, 3), v = Points::Constant(200, 3, 0.1);
  for (int i = 0; i < 200; ++i) {
    const double angle = 0.1 * i;
    x.row(i) = (kCenter + Eigen::Vector3d(std::cos(angle), std::sin(0.3 * i), std::sin(angle))
                              .normalized() * (0.24 + 0.0003 * i)).transpose();
  }
  std::vector<Contact> contacts;
  contacts.reserve(x.rows());
  const TestMesh moved = test::Translated(sphere, Eigen::Vector3d(0.001, 0.002, 0.0));
  collider.Update(kJoints, sphere.vertices, kH);
  collider.FindContacts(x, v, kH, 0.003, contacts);
  Points x2 = x, v2 = v;
  collider.ProjectOut(x2, v2);
  ASSERT_GT(contacts.size(), 10u);
  contacts.clear();
  g_num_allocations = 0;
  g_count_allocations = true;
  collider.Update(kJoints, moved.vertices, kH);
  collider.FindContacts(x, v, kH, 0.003, contacts);
  collider.ProjectOut(x, v);
  g_count_allocations = false;
  EXPECT_EQ(g_num_allocations, 0);
  // The counter works: a vector's first push allocates.
  std::vector<int> probe;
  g_count_allocations = true;
  probe.push_back(1);
  g_count_allocations = false;
  EXPECT_EQ(g_num_allocations, 1);
}

TEST(MeshCollider, RefusesBadOptions) {
  const auto avatar = RigidAvatar(test::TessellatedBox(kCenter, kHalf, Eigen::Vector3i(2, 2, 2)));
  MeshCollisionOptions options;
  options.region_size = 0;
  EXPECT_THROW(MeshCollider(avatar, BodyCollisionSettings{}, options), InputError);
  options = {};
  options.flatness_angle = 2.0;
  EXPECT_THROW(MeshCollider(avatar, BodyCollisionSettings{}, options), InputError);
  BodyCollisionSettings settings;
  settings.thickness = -0.001;
  EXPECT_THROW(MeshCollider(avatar, settings), InputError);
}

}  // namespace
}  // namespace costume::sim
