// The superquadric collider on a hand-built avatar: a capsule skinned rigidly to one joint,
// whose true skin distance is the closed form |p − axis segment| − r. Contacts, projection
// and the moving body's normal velocity are checked against it and against hand computation.
#include "sim_core/collision/superquadric_collider.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <numbers>
#include <utility>

#include "sim_core/avatar/clip.h"
#include "sim_core/avatar/pose.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/avatar/procedural_humanoid.h"
#include "sim_core/avatar/skeleton.h"
#include "sim_core/collision/mesh_distance.h"
#include "sim_core/common/input_error.h"

#include "tests/sim_core/collision/test_meshes.h"
#include "tests/support/count_mallocs.h"

namespace costume::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kRadius = 0.05;                 // capsule radius [m]
constexpr double kHalfLength = 0.1;              // half length of its cylinder [m]
constexpr double kThickness = 0.004;             // cloth thickness [m]
const Eigen::Vector3d kCentre(0.0, -0.15, 0.0);  // capsule centre in the arm joint's frame;
                                                 // its axis is the joint's y axis

/// Signed distance of `local` (arm joint frame) from the capsule's skin [m], > 0 outside.
/// The points `local` placed by `frame`, one per row [m].
Points At(const std::vector<Eigen::Vector3d>& local,
          const Eigen::Isometry3d& frame = Eigen::Isometry3d::Identity()) {
  Points points(static_cast<Eigen::Index>(local.size()), 3);
  for (std::size_t i = 0; i < local.size(); ++i) points.row(i) = (frame * local[i]).transpose();
  return points;
}

double CapsuleDistance(const Eigen::Vector3d& local) {
  const Eigen::Vector3d p = local - kCentre;
  const double s = std::clamp(p.y(), -kHalfLength, kHalfLength);
  return (p - Eigen::Vector3d(0, s, 0)).norm() - kRadius;
}

/// Outward normal of the capsule at `local` (arm joint frame).
Eigen::Vector3d CapsuleNormal(const Eigen::Vector3d& local) {
  const Eigen::Vector3d p = local - kCentre;
  const double s = std::clamp(p.y(), -kHalfLength, kHalfLength);
  return (p - Eigen::Vector3d(0, s, 0)).normalized();
}

/// Capsule surface point at axial position `axial` from the centre (|axial| <= half length:
/// cylinder) and angle `theta` about the axis, pushed out by `offset` [m] (arm joint frame).
Eigen::Vector3d SidePoint(double axial, double theta, double offset) {
  return kCentre + Eigen::Vector3d((kRadius + offset) * std::cos(theta), axial,
                                   (kRadius + offset) * std::sin(theta));
}

/// Appends to `local` and `triangles` a capsule of kRadius around `centre` whose axis is y,
/// its cylinder kHalfLength either side: 64 × 41 rings, counter-clockwise from outside.
void AppendCapsule(const Eigen::Vector3d& centre, std::vector<Eigen::Vector3d>& local,
                   std::vector<Eigen::Vector3i>& triangles) {
  const int base = static_cast<int>(local.size());
  // Rings (axial position, radius) from the bottom pole to the top pole.
  const int around = 64, cap_rings = 16, cylinder_rings = 10;
  std::vector<std::pair<double, double>> rings;
  for (int i = 1; i <= cap_rings; ++i) {
    const double phi = i * (kPi / 2) / cap_rings;
    rings.push_back({-kHalfLength - kRadius * std::cos(phi), kRadius * std::sin(phi)});
  }
  for (int m = 1; m < cylinder_rings; ++m) {
    rings.push_back({-kHalfLength + 2 * kHalfLength * m / cylinder_rings, kRadius});
  }
  for (int i = cap_rings; i >= 1; --i) {
    const double phi = i * (kPi / 2) / cap_rings;
    rings.push_back({kHalfLength + kRadius * std::cos(phi), kRadius * std::sin(phi)});
  }
  local.push_back(centre + Eigen::Vector3d(0, -kHalfLength - kRadius, 0));
  for (const auto& [axial, radius] : rings) {
    for (int k = 0; k < around; ++k) {
      const double theta = 2 * kPi * k / around;
      local.push_back(centre +
                      Eigen::Vector3d(radius * std::cos(theta), axial, radius * std::sin(theta)));
    }
  }
  local.push_back(centre + Eigen::Vector3d(0, kHalfLength + kRadius, 0));
  const int top = static_cast<int>(local.size()) - 1;
  const auto ring_vertex = [&](int ring, int k) { return base + 1 + ring * around + (k % around); };
  for (int k = 0; k < around; ++k) {
    triangles.push_back({base, ring_vertex(0, k), ring_vertex(0, k + 1)});
    for (int ring = 0; ring + 1 < static_cast<int>(rings.size()); ++ring) {
      triangles.push_back(
          {ring_vertex(ring, k), ring_vertex(ring + 1, k), ring_vertex(ring + 1, k + 1)});
      triangles.push_back(
          {ring_vertex(ring, k), ring_vertex(ring + 1, k + 1), ring_vertex(ring, k + 1)});
    }
    const int last = static_cast<int>(rings.size()) - 1;
    triangles.push_back({top, ring_vertex(last, k + 1), ring_vertex(last, k)});
  }
}

/// Two joints: a root and an arm (l_shoulder) placed and turned arbitrarily; a capsule mesh
/// skinned rigidly to the arm, and five loose vertices on the root (too few to fit). Any
/// `extra` closed pieces (arm joint frame) are skinned to the arm too.
std::shared_ptr<const Avatar> MakeCapsuleAvatar(const std::vector<test::TestMesh>& extra = {}) {
  std::vector<Joint> joints(2);
  joints[0].name = "root";
  joints[0].hanim = HAnimJoint::kHumanoidRoot;
  joints[1].name = "arm";
  joints[1].parent = 0;
  joints[1].hanim = HAnimJoint::kLShoulder;
  joints[1].rest_local = Eigen::Translation3d(0.2, 1.4, 0.1) *
                         Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.3, 1.0, 0.2).normalized());
  AvatarData data;
  data.name = "capsule";
  data.skeleton = Skeleton::Create("capsule", joints);
  const Eigen::Isometry3d arm = data.skeleton->rest_world()[1];
  std::vector<Eigen::Vector3d> local;
  AppendCapsule(kCentre, local, data.triangles);
  for (const test::TestMesh& piece : extra) {
    const int first = static_cast<int>(local.size());
    for (Eigen::Index v = 0; v < piece.vertices.rows(); ++v) {
      local.push_back(piece.vertices.row(v).transpose());
    }
    for (const Eigen::Vector3i& t : piece.triangles) {
      data.triangles.push_back(t + Eigen::Vector3i::Constant(first));
    }
  }
  const int num_capsule = static_cast<int>(local.size());
  const int num_loose = 5;
  data.rest_vertices.resize(num_capsule + num_loose, 3);
  data.influence_joints.setConstant(num_capsule + num_loose, kMaxInfluences, -1);
  data.influence_weights.setZero(num_capsule + num_loose, kMaxInfluences);
  for (int v = 0; v < num_capsule; ++v) {
    data.rest_vertices.row(v) = (arm * local[v]).transpose();
    data.influence_joints(v, 0) = 1;
    data.influence_weights(v, 0) = 1.0;
  }
  for (int v = num_capsule; v < num_capsule + num_loose; ++v) {
    data.rest_vertices.row(v) << 0.01 * v, 0.9, 0.0;
    data.influence_joints(v, 0) = 0;
    data.influence_weights(v, 0) = 1.0;
  }
  return Avatar::Create(std::move(data));
}

struct Fixture : ::testing::Test {
  std::shared_ptr<const Avatar> avatar = MakeCapsuleAvatar();
  BodyCollisionSettings settings{kThickness, 0.5};
  SuperquadricCollider collider{avatar, settings};
  Eigen::Isometry3d arm = avatar->skeleton().rest_world()[1];
  Points unused_skin;

  /// The joint frames with the arm moved `distance` [m] along its own x axis from rest.
  std::vector<Eigen::Isometry3d> ArmMovedAlongX(double distance) const {
    std::vector<Eigen::Isometry3d> world = avatar->skeleton().rest_world();
    world[1] = Eigen::Translation3d(distance * arm.linear().col(0)) * world[1];
    return world;
  }
};

TEST_F(Fixture, FitsTheCapsuleAndSkipsTheSegmentWithTooFewVertices) {
  ASSERT_EQ(collider.segments().size(), 1u);
  EXPECT_EQ(collider.segments()[0].segment, HAnimJoint::kLShoulder);
  ASSERT_EQ(collider.skipped_segments().size(), 1u);
  EXPECT_EQ(collider.skipped_segments()[0], HAnimJoint::kHumanoidRoot);
  const std::vector<SegmentSuperquadricFit> fits = FitAvatarSegments(*avatar);
  ASSERT_EQ(fits.size(), 2u);
  EXPECT_FALSE(fits[0].fitted);
  EXPECT_EQ(fits[0].num_vertices, 5);
  EXPECT_TRUE(fits[1].fitted);
  EXPECT_EQ(fits[1].joint, 1);
  // A superquadric cannot be a capsule exactly, but comes within millimetres of one, and
  // its long axis is the capsule's (the joint's y axis).
  EXPECT_LT(fits[1].fit.rms_radial_distance, 0.005);
  const Superquadric& sq = fits[1].fit.superquadric;
  EXPECT_NEAR(std::abs(sq.frame.linear().col(2).dot(Eigen::Vector3d::UnitY())), 1.0, 1e-3);
  EXPECT_LT((sq.frame.translation() - kCentre).norm(), 0.002);
}

/// Depth of the particles ExpectInsideParticlesResolved puts inside the skin [m]: within
/// what a step could carry them from outside the shell (PlausibleDepth at rest: thickness
/// plus the map's 1 cm node spacing), so the map's readings hold.
constexpr double kDepth = 0.007;

/// Particles kDepth inside the skin at three places get a contact and project onto the
/// shell. `min_normal_dot`: the least cosine allowed between contact and true skin normals.
void ExpectInsideParticlesResolved(SuperquadricCollider& collider, const Avatar& avatar,
                                   double min_normal_dot) {
  collider.Update(avatar.skeleton().rest_world(), Points(), 0.01);
  const Eigen::Isometry3d& arm = avatar.skeleton().rest_world()[1];
  const std::vector<Eigen::Vector3d> local = {
      SidePoint(0.03, 0.7, -kDepth),   // cylinder side
      SidePoint(-0.08, 2.5, -kDepth),  // its ray meets the skin where cylinder and cap join
      kCentre + Eigen::Vector3d(0, kHalfLength, 0) +
          (kRadius - kDepth) * Eigen::Vector3d(0.5, 1.0, -0.3).normalized(),  // top cap
  };
  Points positions(3, 3);
  for (int i = 0; i < 3; ++i) positions.row(i) = (arm * local[i]).transpose();
  Points velocities = Points::Zero(3, 3);
  const double h = 0.01;
  std::vector<Contact> contacts;
  collider.FindContacts(positions, velocities, h, 0.001, contacts);
  ASSERT_EQ(contacts.size(), 3u);
  EXPECT_EQ(collider.stats().num_contacts, 3);
  for (const Contact& c : contacts) {
    const Eigen::Vector3d true_normal = arm.linear() * CapsuleNormal(local[c.particle]);
    EXPECT_GT(c.normal.dot(true_normal), min_normal_dot) << c.particle;
    EXPECT_NEAR(c.normal.norm(), 1.0, 1e-12);
    // The depth plus thickness, removed within the step: within 0.5 mm of the true gap.
    EXPECT_NEAR(c.target_normal_velocity, (kDepth + kThickness) / h, 0.05) << c.particle;
    EXPECT_DOUBLE_EQ(c.friction, 0.5);
  }
  for (int i = 0; i < 3; ++i) {
    velocities.row(i) = -2.0 * (arm.linear() * CapsuleNormal(local[i])).transpose();
  }
  const double deepest = collider.ProjectOut(positions, velocities);
  // Radially at least the normal depth.
  EXPECT_GT(deepest, kDepth + kThickness - 0.0005);
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d moved = arm.inverse() * positions.row(i).transpose();
    EXPECT_NEAR(CapsuleDistance(moved), kThickness, 0.001) << i;
    // The inward 2 m/s along the true normal is removed along the contact normal: what
    // remains along the true normal is at most 2·(1 − cos²).
    const Eigen::Vector3d true_normal = arm.linear() * CapsuleNormal(moved);
    EXPECT_GT(velocities.row(i).dot(true_normal),
              -2.0 * (1 - min_normal_dot * min_normal_dot) - 0.01)
        << i;
  }
}

TEST_F(Fixture, AParticleInsideTheSkinGetsAnOutwardContactAndProjectsOntoTheShell) {
  // The superquadric's gradient departs from the capsule's normal by up to 24° where the
  // rounded cap meets the superquadric's flatter end (the documented approximation).
  ExpectInsideParticlesResolved(collider, *avatar, 0.9);
}

TEST_F(Fixture, SkinNormalsFromTheMapFollowTheTrueSkin) {
  SuperquadricColliderOptions options;
  options.contact_normal = SuperquadricColliderOptions::ContactNormal::kSkin;
  SuperquadricCollider skin_collider(avatar, settings, options);
  ExpectInsideParticlesResolved(skin_collider, *avatar, 0.99);
}

// A reading deeper than the step could have carried the particle from outside the shell
// (PlausibleDepth) is not trusted, even from nodes that saw skin: on MakeHuman such
// readings pushed cloth by 3–15 cm (a star-shaped shell misjudging a crease), and the
// suit's strain reached 2,000 %. Particles 3 cm inside the resting capsule get no contact
// from the map, and ProjectOut hands them to the skin triangles, which put them on the
// true shell (closed form).
/// Two points 3 cm inside the capsule, moving at `velocities`: no contact from the map, and
/// ProjectOut puts both on the true shell through the skin triangles.
void ExpectDeepPointsDecidedByTheSkinTriangles(Fixture& f, const Points& velocities) {
  const std::vector<Eigen::Vector3d> local = {SidePoint(0.03, 0.7, -0.03),
                                              SidePoint(-0.05, -1.9, -0.03)};
  Points positions = At(local, f.arm);
  Points moving = velocities;
  std::vector<Contact> contacts;
  f.collider.FindContacts(positions, moving, 0.01, 0.001, contacts);
  EXPECT_TRUE(contacts.empty());
  f.collider.ProjectOut(positions, moving);
  EXPECT_EQ(f.collider.stats().num_skin_checks, 2);
  for (int i = 0; i < 2; ++i) {
    const Eigen::Vector3d moved = f.arm.inverse() * positions.row(i).transpose();
    EXPECT_NEAR(CapsuleDistance(moved), kThickness, 0.001) << i;
  }
}

TEST_F(Fixture, AReadingDeeperThanTheStepAllowsGoesToTheSkinTriangles) {
  collider.Update(avatar->skeleton().rest_world(), Points(), 0.01);
  ExpectDeepPointsDecidedByTheSkinTriangles(*this, Points::Zero(2, 3));
}

// The same points sliding along the capsule at 5 m/s (5 cm a step): the particle's own speed
// does not make the reading plausible, only the body's motion does. Counted with the
// particle's speed, MakeHuman's upper arm, whose rays pass through the armpit into the
// torso, read the suit's collar sliding down the chest 41 mm deep and threw it 43 mm along
// the skin (docs/collision.md, "The suit's worst frames now"); here the points got contacts
// and ended off the shell.
TEST_F(Fixture, AParticleSlidingFastAlongTheSkinIsNoMoreTrustedDeep) {
  // Twice: the second Update is a step of 0.01 s (the first only places the body).
  collider.Update(avatar->skeleton().rest_world(), Points(), 0.01);
  collider.Update(avatar->skeleton().rest_world(), Points(), 0.01);
  const Eigen::Vector3d along = arm.linear() * Eigen::Vector3d(0.0, 5.0, 0.0);
  Points velocities(2, 3);
  velocities.row(0) = along.transpose();
  velocities.row(1) = -along.transpose();
  ExpectDeepPointsDecidedByTheSkinTriangles(*this, velocities);
}

// The map is redrawn from the skinned vertices Update is given, not kept from the rest
// pose: a skin inflated by 1 cm about the capsule's axis (as skinning swells a bent joint)
// moves the shell out by 1 cm, which the inflated capsule's closed form checks.
/// The capsule's skin swollen by `swell` [m] along its outward normal (along the axis at
/// the poles).
Points SwollenSkin(const Avatar& avatar, const Eigen::Isometry3d& arm, double swell) {
  Points skinned = avatar.rest_vertices();
  const Eigen::Isometry3d to_arm = arm.inverse();
  for (Eigen::Index v = 0; v < skinned.rows(); ++v) {
    const Eigen::Vector3d local = to_arm * skinned.row(v).transpose();
    const Eigen::Vector3d p = local - kCentre;
    const double s = std::clamp(p.y(), -kHalfLength, kHalfLength);
    const Eigen::Vector3d radial = p - Eigen::Vector3d(0, s, 0);
    const Eigen::Vector3d out = radial.norm() < 1e-9
                                    ? Eigen::Vector3d(0.0, p.y() > 0 ? 1.0 : -1.0, 0.0)
                                    : Eigen::Vector3d(radial.normalized());
    skinned.row(v) = (arm * (local + swell * out)).transpose();
  }
  return skinned;
}

TEST_F(Fixture, TheMapFollowsTheSkinnedVertices) {
  constexpr double kSwell = 0.01;
  const Points skinned = SwollenSkin(*avatar, arm, kSwell);
  const Eigen::Isometry3d to_arm = arm.inverse();
  collider.Update(avatar->skeleton().rest_world(), skinned, 0.01);
  // 5 mm outside the rest skin is 5 mm inside the swollen one: a contact whose target
  // closes 5 mm + thickness in the step, and a projection onto the swollen shell.
  Points positions = At({SidePoint(0.02, 0.9, 0.005), SidePoint(-0.05, -2.0, 0.005)}, arm);
  Points velocities = Points::Zero(2, 3);
  std::vector<Contact> contacts;
  const double h = 0.01;
  collider.FindContacts(positions, velocities, h, 0.001, contacts);
  ASSERT_EQ(contacts.size(), 2u);
  for (const Contact& c : contacts) {
    EXPECT_NEAR(c.target_normal_velocity, (kSwell - 0.005 + kThickness) / h, 0.05) << c.particle;
  }
  collider.ProjectOut(positions, velocities);
  for (int i = 0; i < 2; ++i) {
    const Eigen::Vector3d moved = to_arm * positions.row(i).transpose();
    EXPECT_NEAR(CapsuleDistance(moved), kSwell + kThickness, 0.001) << i;
  }
  // Back to the rest skin: the same points are outside its shell again.
  collider.Update(avatar->skeleton().rest_world(), avatar->rest_vertices(), 0.01);
  positions = At({SidePoint(0.02, 0.9, 0.005), SidePoint(-0.05, -2.0, 0.005)}, arm);
  contacts.clear();
  collider.FindContacts(positions, velocities, h, 0.001, contacts);
  for (const Contact& c : contacts) {
    // Outside the shell, within the margin, at rest on a body at rest: held where they are,
    // neither pushed out nor pulled in (contact.h).
    EXPECT_NEAR(c.target_normal_velocity, 0.0, 1e-9) << c.particle;
  }
}

// Drawings are stored for reuse (skin_map_cache.h). The skin swollen by 1 cm, then 2 cm,
// then 1 cm again: the third map comes from the store, the second (another skin) does not,
// and each time the points are projected onto the swollen capsule's shell (closed form).
TEST_F(Fixture, AStoredDrawingIsReusedOnlyForTheSameSkin) {
  const std::vector<Eigen::Vector3d> local = {SidePoint(0.02, 0.9, 0.0),
                                              SidePoint(-0.05, -2.0, 0.0)};
  const auto project = [&](double swell, int expect_drawn, int expect_reused) {
    collider.Update(avatar->skeleton().rest_world(), SwollenSkin(*avatar, arm, swell), 0.01);
    Points positions = At(local, arm);
    Points velocities = Points::Zero(2, 3);
    std::vector<Contact> contacts;
    collider.FindContacts(positions, velocities, 0.01, 0.001, contacts);
    collider.ProjectOut(positions, velocities);
    EXPECT_EQ(collider.stats().num_maps_drawn, expect_drawn) << swell;
    EXPECT_EQ(collider.stats().num_maps_reused, expect_reused) << swell;
    for (int i = 0; i < 2; ++i) {
      const Eigen::Vector3d moved = arm.inverse() * positions.row(i).transpose();
      EXPECT_NEAR(CapsuleDistance(moved), swell + kThickness, 0.001) << swell << " " << i;
    }
  };
  project(0.01, 1, 0);
  project(0.02, 1, 0);
  project(0.01, 0, 1);
  EXPECT_EQ(collider.map_cache_stats().num_hits, 1);
  // Without a store every map is drawn, and the shells agree.
  SuperquadricColliderOptions options;
  options.map_cache_bytes = 0;
  SuperquadricCollider fresh(avatar, settings, options);
  fresh.Update(avatar->skeleton().rest_world(), SwollenSkin(*avatar, arm, 0.01), 0.01);
  const Points positions = At(local, arm);
  const Points velocities = Points::Zero(2, 3);
  std::vector<Contact> stored_contacts, fresh_contacts;
  collider.FindContacts(positions, velocities, 0.01, 0.001, stored_contacts);
  fresh.FindContacts(positions, velocities, 0.01, 0.001, fresh_contacts);
  EXPECT_EQ(fresh.stats().num_maps_reused, 0);
  ASSERT_EQ(stored_contacts.size(), fresh_contacts.size());
  for (std::size_t c = 0; c < fresh_contacts.size(); ++c) {
    EXPECT_NEAR(stored_contacts[c].target_normal_velocity,
                fresh_contacts[c].target_normal_velocity, 1e-4);  // 1 µm over 10 ms
    EXPECT_LT((stored_contacts[c].normal - fresh_contacts[c].normal).norm(), 1e-4);
  }
}

TEST_F(Fixture, AParticleFiveCentimetresOutsideGetsNoContactAndStays) {
  collider.Update(avatar->skeleton().rest_world(), unused_skin, 0.01);
  Points positions = At({SidePoint(0.0, 1.0, 0.05), SidePoint(0.1, -2.0, 0.05)}, arm);
  const Points before = positions;
  Points velocities = Points::Zero(2, 3);
  std::vector<Contact> contacts;
  collider.FindContacts(positions, velocities, 0.01, 0.001, contacts);
  EXPECT_TRUE(contacts.empty());
  EXPECT_EQ(collider.ProjectOut(positions, velocities), 0.0);
  EXPECT_EQ(positions, before);
}

// Outside the shell a contact never pulls (contact.h): particles 1.5 mm outside the shell of
// the arm at rest, within the margin, keep their own normal velocity, leaving (5 cm/s),
// still, or approaching slowly (3 cm/s: 0.3 mm closer within the step); one approaching at
// 0.5 m/s, which would cross the shell within the step, is landed on it: −1.5 mm / h. (Each
// was landed on the shell before: −0.15 m/s.)
TEST_F(Fixture, AContactOutsideTheShellNeverPullsTheParticleIn) {
  collider.Update(avatar->skeleton().rest_world(), unused_skin, 0.01);
  const double h = 0.01, gap = 0.0015;
  const std::vector<double> speeds = {0.05, 0.0, -0.03, -0.5};
  const int n = static_cast<int>(speeds.size());
  std::vector<Eigen::Vector3d> local;
  Points velocities(n, 3);
  for (int i = 0; i < n; ++i) {
    local.push_back(SidePoint(0.02 * i - 0.03, 0.5 + 1.5 * i, kThickness + gap));
    velocities.row(i) = (speeds[i] * (arm.linear() * CapsuleNormal(local.back()))).transpose();
  }
  const Points positions = At(local, arm);
  std::vector<Contact> contacts;
  collider.FindContacts(positions, velocities, h, 0.002, contacts);
  ASSERT_EQ(static_cast<int>(contacts.size()), n);
  for (int i = 0; i + 1 < n; ++i) {
    EXPECT_EQ(contacts[i].particle, i);
    EXPECT_NEAR(contacts[i].target_normal_velocity, speeds[i], 1e-3) << i;
  }
  EXPECT_NEAR(contacts[n - 1].target_normal_velocity, -gap / h, 0.05);
}

TEST_F(Fixture, ContactsFollowTheMovingBodyAndCarryItsNormalVelocity) {
  collider.Update(avatar->skeleton().rest_world(), unused_skin, 0.01);
  // The arm moves 2 cm along its own x axis in dt = h = 10 ms: body velocity 2 m/s.
  const double dt = 0.01, h = 0.01;
  const Eigen::Vector3d axis_x = arm.linear().col(0);
  const std::vector<Eigen::Isometry3d> world = ArmMovedAlongX(0.02);
  collider.Update(world, unused_skin, dt);
  // Particle 0: 1 cm outside the old skin on the +x side, so 1 cm inside the new one.
  // Particle 1: 5 mm inside the old skin on the −x side, left 4.5 cm behind by a body that
  // moves away from it: inside the shell, it is held to the receding surface (as the mesh
  // collider holds cloth inside its shell), however its velocity would carry it.
  Points positions = At({SidePoint(0.0, 0.0, 0.01), SidePoint(0.0, kPi, -0.005)}, arm);
  Points velocities = Points::Zero(2, 3);
  std::vector<Contact> contacts;
  collider.FindContacts(positions, velocities, h, 0.001, contacts);
  ASSERT_EQ(contacts.size(), 2u);
  const Contact& c = contacts[0];
  EXPECT_EQ(c.particle, 0);
  EXPECT_GT(c.normal.dot(axis_x), 0.999);
  // Hand computation: body normal velocity 0.02/dt = 2 m/s, minus the start gap
  // (1 cm − thickness) closed within h: 2 − 0.006/0.01 = 1.4 m/s.
  const double expected = 0.02 / dt - (0.01 - kThickness) / h;
  EXPECT_NEAR(c.target_normal_velocity, expected, 0.05);
  // Particle 1: normal −x, the body's normal velocity −2 m/s, plus the start depth
  // (5 mm + thickness) made good within h: −2 + 0.009/0.01 = −1.1 m/s.
  const Contact& behind = contacts[1];
  EXPECT_EQ(behind.particle, 1);
  EXPECT_GT(behind.normal.dot(-axis_x), 0.999);
  EXPECT_NEAR(behind.target_normal_velocity, -0.02 / dt + (0.005 + kThickness) / h, 0.05);

  // Projection uses the end pose: particle 0 lands on the moved shell and takes the body's
  // normal velocity; particle 1 is outside the moved body and stays.
  const Points before = positions;
  collider.ProjectOut(positions, velocities);
  const Eigen::Isometry3d moved_arm = world[1];
  EXPECT_NEAR(CapsuleDistance(moved_arm.inverse() * positions.row(0).transpose()), kThickness,
              0.001);
  EXPECT_NEAR(velocities.row(0).dot(axis_x), 0.02 / dt, 0.05);
  EXPECT_EQ(positions.row(1), before.row(1));
}

// Restarted, the collider forgets the pose before: the arm moved 2 cm, as above, has no
// velocity now, and a particle within its shell is only pushed onto the shell.
TEST_F(Fixture, ARestartedColliderTakesTheNextPoseWithoutVelocity) {
  collider.Update(avatar->skeleton().rest_world(), unused_skin, 0.01);
  const double h = 0.01;
  const Eigen::Vector3d axis_x = arm.linear().col(0);
  const std::vector<Eigen::Isometry3d> world = ArmMovedAlongX(0.02);
  collider.Restart();
  collider.Update(world, unused_skin, 0.01);
  // 2 mm outside the moved skin on the +x side: 2 mm inside the 4 mm shell.
  Points positions = At({SidePoint(0.0, 0.0, 0.002)}, world[1]);
  Points velocities = Points::Zero(1, 3);
  std::vector<Contact> contacts;
  collider.FindContacts(positions, velocities, h, 0.001, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  // Hand computation: the 2 mm made good within h, 0.002 / 0.01 = 0.2 m/s. (Not restarted,
  // the same: tested against the arm 2 cm back, moving at 2 m/s, 2 − 1.8.)
  EXPECT_GT(contacts[0].normal.dot(axis_x), 0.999);
  EXPECT_NEAR(contacts[0].target_normal_velocity, (kThickness - 0.002) / h, 0.05);
  // Pushed onto the shell, the particle keeps its velocity, 0: the body does not move (not
  // restarted, it would take the arm's 2 m/s).
  collider.ProjectOut(positions, velocities);
  EXPECT_NEAR(CapsuleDistance(world[1].inverse() * positions.row(0).transpose()), kThickness,
              0.001);
  EXPECT_NEAR(velocities.row(0).norm(), 0.0, 1e-9);
}

// Restarted, the collider keeps its stored drawings while they fill at most half the
// store, so the same skin is not drawn again; beyond half they are forgotten, so that
// another motion's drawings find room.
// A thickness set on a collider gives the contacts and corrections of one built with it,
// though it reads the drawings it stored before (a drawing holds the skin, its shell's
// bounds are set for the thickness of the reading).
TEST_F(Fixture, ANewThicknessActsAsAColliderBuiltWithIt) {
  const std::vector<Eigen::Isometry3d>& rest = avatar->skeleton().rest_world();
  collider.Update(rest, avatar->rest_vertices(), 0.01);
  collider.RefreshAllMaps();
  collider.SetThickness(0.015);
  SuperquadricCollider built(avatar, {0.015, settings.friction});
  built.Update(rest, avatar->rest_vertices(), 0.01);  // the same history of poses
  const auto step = [&](SuperquadricCollider& c, Points& x, std::vector<Contact>& contacts) {
    c.Update(rest, avatar->rest_vertices(), 0.01);
    Points v = Points::Zero(x.rows(), 3);
    c.FindContacts(x, v, 0.01, 0.001, contacts);
    c.ProjectOut(x, v);
  };
  const Points start = At({SidePoint(0.0, 0.0, 0.005), SidePoint(0.02, 1.3, 0.012),
                           SidePoint(-0.03, 2.6, 0.002), SidePoint(0.01, 4.0, 0.03)},
                          arm);
  Points set_x = start, built_x = start;
  std::vector<Contact> set_contacts, built_contacts;
  step(collider, set_x, set_contacts);
  step(built, built_x, built_contacts);
  EXPECT_GT(collider.map_cache_stats().num_hits, 0);
  ASSERT_EQ(set_contacts.size(), 3u);  // the three within 15 mm of the skin
  ASSERT_EQ(built_contacts.size(), set_contacts.size());
  for (std::size_t c = 0; c < set_contacts.size(); ++c) {
    EXPECT_EQ(set_contacts[c].target_normal_velocity, built_contacts[c].target_normal_velocity);
  }
  EXPECT_EQ(set_x, built_x);
  // On the new shell: 15 mm off the capsule.
  EXPECT_NEAR(CapsuleDistance(arm.inverse() * set_x.row(0).transpose()), 0.015, 0.001);
}

TEST_F(Fixture, ARestartKeepsTheDrawingsOfAStoreAtMostHalfFull) {
  const std::size_t rest_bytes = collider.map_cache_stats().bytes_used;  // the rest pose's
  ASSERT_GT(rest_bytes, 0u);
  const auto drawn_after_restart = [&](std::size_t budget) {
    SuperquadricColliderOptions options;
    options.map_cache_bytes = budget;
    SuperquadricCollider kept(avatar, settings, options);
    kept.Restart();
    kept.Update(avatar->skeleton().rest_world(), avatar->rest_vertices(), 0.01);
    kept.RefreshAllMaps();
    return kept.stats().num_maps_drawn;
  };
  EXPECT_EQ(drawn_after_restart(4 * rest_bytes), 0);
  EXPECT_EQ(drawn_after_restart(rest_bytes * 3 / 2), 1);
}

TEST_F(Fixture, SegmentsFarFromTheClothAreNotTested) {
  collider.Update(avatar->skeleton().rest_world(), unused_skin, 0.01);
  Points far = Points::Constant(4, 3, 10.0);
  Points velocities = Points::Zero(4, 3);
  std::vector<Contact> contacts;
  collider.FindContacts(far, velocities, 0.01, 0.001, contacts);
  EXPECT_EQ(collider.stats().num_tests, 0);
  Points near =
      At({SidePoint(0, 0, 0.2), SidePoint(0, 1, 0.3), SidePoint(0, 2, 0.2), SidePoint(0, 3, 0.3)},
         arm);
  collider.FindContacts(near, velocities, 0.01, 0.001, contacts);
  EXPECT_EQ(collider.stats().num_tests, 4);
  EXPECT_TRUE(contacts.empty());
}

TEST_F(Fixture, FindContactsAndProjectOutDoNotAllocateAfterTheFirstCall) {
  std::vector<Eigen::Isometry3d> world = avatar->skeleton().rest_world();
  collider.Update(world, unused_skin, 0.01);
  Points positions = At({SidePoint(0.0, 0.0, -0.01), SidePoint(0.0, 1.0, 0.02)}, arm);
  Points velocities = Points::Zero(2, 3);
  std::vector<Contact> contacts;
  contacts.reserve(16);
  collider.FindContacts(positions, velocities, 0.01, 0.001, contacts);
  collider.ProjectOut(positions, velocities);
  world[1] = Eigen::Translation3d(0.01, 0.0, 0.0) * world[1];
  Points skinned = avatar->rest_vertices();
  skinned.rowwise() += Eigen::RowVector3d(0.01, 0.0, 0.0);
  g_num_allocations = 0;
  g_count_allocations = true;
  {  // The counter sees Eigen's heap and operator new.
    Eigen::VectorXd probe(64);
    probe.setZero();
    EXPECT_GE(g_num_allocations, 1);
  }
  g_num_allocations = 0;
  collider.Update(world, unused_skin, 0.01);
  contacts.clear();
  collider.FindContacts(positions, velocities, 0.01, 0.001, contacts);
  collider.ProjectOut(positions, velocities);
  // With skin, the maps are redrawn in FindContacts: no allocation either.
  collider.Update(world, skinned, 0.01);
  contacts.clear();
  collider.FindContacts(positions, velocities, 0.01, 0.001, contacts);
  collider.ProjectOut(positions, velocities);
  collider.RefreshAllMaps();
  // The same skin again: its stored drawing is put back, without allocating.
  collider.Update(world, skinned, 0.01);
  contacts.clear();
  collider.FindContacts(positions, velocities, 0.01, 0.001, contacts);
  collider.ProjectOut(positions, velocities);
  EXPECT_GE(collider.stats().num_maps_reused, 1);
  g_count_allocations = false;
  EXPECT_EQ(g_num_allocations, 0);
}

/// A collider for `avatar` as the simulation builds it: contact normals from the skin, the
/// tests' cloth thickness.
std::unique_ptr<SuperquadricCollider> SimulationCollider(std::shared_ptr<const Avatar> avatar) {
  SuperquadricColliderOptions options;
  options.contact_normal = SuperquadricColliderOptions::ContactNormal::kSkin;
  BodyCollisionSettings settings;
  settings.thickness = kThickness;
  return std::make_unique<SuperquadricCollider>(std::move(avatar), settings, options);
}

// The still layer (superquadric_map.cc, DrawExits): a drawing keeps the exits of the skin
// that has not moved in the segment's frame and rasterises only the rest. Through the
// built-in kick's frames, a pose held (the layer then holds every exit), poses moving the
// leg (layer corners move: drawn afresh) and the leg at rest again, every map the collider
// draws matches the map a new collider draws of that skin alone, node for node: the same
// radius to 1 nm, the same capped nodes, the same normal. (When the corners at rest were
// not drawn exactly where they were anchored, 1–22 nodes a segment differed, radii by up to
// 0.7 mm; when a layer corner's move went unnoticed, up to 1,082.)
TEST(SuperquadricCollider, AMapDrawnOverItsStillLayerIsTheMapOfItsSkin) {
  const std::shared_ptr<const Avatar> humanoid = MakeHumanoid();
  const Clip kick = MakeBuiltInClip("kick", humanoid->shared_skeleton());
  SuperquadricColliderOptions options;
  options.map_cache_bytes = 0;  // every map drawn
  const BodyCollisionSettings settings{kThickness, 0.5};
  SuperquadricCollider collider(humanoid, settings, options);
  int layered = 0;
  for (double t : {0.3, 0.3, 0.35, 0.42, 0.42, 0.42, 0.5}) {
    Pose pose;
    SampleClip(kick, t, pose);
    std::vector<Eigen::Isometry3d> world, skinning;
    ComputeJointWorld(humanoid->skeleton(), pose, world);
    Points skin;
    SkinVertices(*humanoid, world, skinning, skin);
    collider.Update(world, skin, 0.01);
    collider.RefreshAllMaps();
    SuperquadricCollider fresh(humanoid, settings, options);
    fresh.Update(world, skin, 0.01);
    fresh.RefreshAllMaps();
    ASSERT_EQ(collider.segments().size(), fresh.segments().size());
    for (std::size_t s = 0; s < fresh.segments().size(); ++s) {
      const SegmentSkin& drawn = collider.segments()[s].skin;
      const SegmentSkin& alone = fresh.segments()[s].skin;
      layered += static_cast<int>(std::count(drawn.in_layer.begin(), drawn.in_layer.end(), 1));
      ASSERT_EQ(drawn.radius.size(), alone.radius.size());
      int differ = 0;
      for (std::size_t n = 0; n < alone.radius.size(); ++n) {
        if (std::abs(drawn.radius[n] - alone.radius[n]) > 1e-9 ||
            drawn.capped[n] != alone.capped[n] ||
            (drawn.normal[n] - alone.normal[n]).norm() > 1e-6) {
          ++differ;
        }
      }
      EXPECT_EQ(differ, 0) << "t = " << t << " s, segment " << s << " of "
                           << alone.radius.size() << " nodes";
    }
  }
  // The layer did take part: held poses put every triangle of a segment in it.
  EXPECT_GT(layered, 10000);
}

/// `avatar` posed at `t` [s] of `clip`: its joints' world frames into `world`, its skinned
/// vertices returned, and `collider` updated to that pose twice, so that it rests there.
Points PoseAtRest(const Avatar& avatar, const Clip& clip, double t,
                  SuperquadricCollider& collider, std::vector<Eigen::Isometry3d>& world) {
  Pose pose;
  SampleClip(clip, t, pose);
  std::vector<Eigen::Isometry3d> skinning;
  ComputeJointWorld(avatar.skeleton(), pose, world);
  Points skin;
  SkinVertices(avatar, world, skinning, skin);
  collider.Update(world, skin, 0.01);
  collider.Update(world, skin, 0.01);
  return skin;
}

/// Where the ray from a segment's centre along the unit `ray` crosses its skin triangles
/// (SegmentSkin::local), by Möller–Trumbore against every triangle, less the parts buried
/// in other pieces of the body (SegmentSkin::burial): distances [m] and +1 leaving the
/// skin, −1 entering it, nearest first. `clear` is false when the ray passes within 1e-6 of
/// a triangle's edge (in barycentric weight), grazes one or meets the edge of a buried
/// part: the drawing may then rightly differ.
struct RayCrossings {
  std::vector<std::pair<double, int>> crossings;
  bool clear = true;
};

RayCrossings CastThroughSkin(const SegmentSkin& skin, const Eigen::Vector3d& ray) {
  RayCrossings out;
  for (std::size_t t = 0; t < skin.triangles.size(); ++t) {
    const Eigen::Vector3d& a = skin.local[skin.triangles[t][0]];
    const Eigen::Vector3d e1 = skin.local[skin.triangles[t][1]] - a;
    const Eigen::Vector3d e2 = skin.local[skin.triangles[t][2]] - a;
    const Eigen::Vector3d p = ray.cross(e2);
    const double det = e1.dot(p);
    const Eigen::Vector3d normal = e1.cross(e2);
    if (std::abs(det) <= 1e-3 * normal.norm()) {  // within 0.06° of the triangle's plane
      if (std::abs(normal.normalized().dot(a)) < 0.05) out.clear = false;  // it may touch
      continue;
    }
    const Eigen::Vector3d to_origin = -a;
    const double u = to_origin.dot(p) / det;
    const Eigen::Vector3d q = to_origin.cross(e1);
    const double v = ray.dot(q) / det;
    const double distance = e2.dot(q) / det;
    if (distance <= 0.0) continue;
    const double nearest_weight = std::min({u, v, 1.0 - u - v});
    if (std::abs(nearest_weight) < 1e-6) out.clear = false;
    if (nearest_weight < 0.0) continue;
    if (skin.partly_buried[t]) {
      // Where the quadratic interpolation of the burial samples (corners, then the edges
      // 1–2, 2–0, 0–1) is negative, the triangle lies inside another piece: not skin.
      const std::array<double, 6>& b = skin.burial[t];
      const double l0 = 1.0 - u - v, l1 = u, l2 = v;
      const double burial = b[0] * l0 * (2 * l0 - 1) + b[1] * l1 * (2 * l1 - 1) +
                            b[2] * l2 * (2 * l2 - 1) +
                            4 * (b[3] * l1 * l2 + b[4] * l2 * l0 + b[5] * l0 * l1);
      if (std::abs(burial) < 1e-7) out.clear = false;
      if (burial < 0.0) continue;
    }
    out.crossings.emplace_back(distance, normal.dot(ray) > 0.0 ? 1 : -1);
  }
  std::sort(out.crossings.begin(), out.crossings.end());
  return out;
}

// How a map is drawn (superquadric_map.cc: the first exits, the rays that enter skin
// before them, and where those leave it for good), checked ray by ray against a cast
// through every skin triangle of the segment. Each node's radius is the distance at
// which its ray first leaves the skin; where the ray enters skin before that (a fold: the
// kick bends hip and knee), it is where the ray, counting entries and exits from 1 at the
// centre, first comes to 0. Nodes whose answer lies beyond the reach, whose ray grazes an
// edge or crosses more than 8 triangles, are left out.
TEST(SuperquadricCollider, EachNodeOfAMapLiesWhereItsRayLeavesTheSkin) {
  const std::shared_ptr<const Avatar> humanoid = MakeHumanoid();
  const Clip kick = MakeBuiltInClip("kick", humanoid->shared_skeleton());
  SuperquadricColliderOptions options;
  options.map_cache_bytes = 0;
  SuperquadricCollider collider(humanoid, {kThickness, 0.5}, options);
  int compared = 0, folded = 0;
  for (double t : {0.3, 0.42}) {
    std::vector<Eigen::Isometry3d> world;
    PoseAtRest(*humanoid, kick, t, collider, world);
    collider.RefreshAllMaps();
    for (std::size_t s = 0; s < collider.segments().size(); ++s) {
      const SuperquadricSegment& segment = collider.segments()[s];
      int wrong = 0;
      for (int node = 0; node < segment.map.num_nodes(); ++node) {
        const RayCrossings cast = CastThroughSkin(segment.skin, segment.map.ray[node]);
        if (!cast.clear || cast.crossings.size() > 8) continue;
        double expected = -1.0;
        bool entered_first = false;
        int winding = 1;
        for (const auto& [distance, sign] : cast.crossings) {
          if (sign < 0 && expected < 0.0) entered_first = true;
          if (sign > 0 && expected < 0.0 && !entered_first) expected = distance;
          winding -= sign;
          if (entered_first && sign > 0 && winding == 0) {
            expected = distance;
            break;
          }
        }
        if (!(expected > 0.0) || expected > segment.reach - 1e-4) continue;
        ++compared;
        if (entered_first) ++folded;
        const bool right = std::abs(segment.skin.radius[node] - expected) < 1e-6 &&
                           (entered_first || !segment.skin.capped[node]);
        if (!right) ++wrong;
      }
      EXPECT_EQ(wrong, 0) << "t = " << t << " s, segment " << s;
    }
  }
  // Most nodes were compared, and folds among them.
  EXPECT_GT(compared, 20000);
  EXPECT_GT(folded, 20);
}

// The creases of bent joints (docs/collision.md, "Joint shells"): the built-in humanoid in
// two frames of its kick (the knee bent 55° behind, then hip 55° and knee 45° forward).
// Points 3 mm inside the true skinned mesh (MeshDistance), within 15 cm of the kicking
// leg's hip and knee, are all pushed out of the skin by ProjectOut. Without the joint
// shells 1 and 3 of about 380 stayed inside (at the buttocks' midline, the groin and beside
// the knee), where no segment's centre sees the skin.
TEST(SuperquadricCollider, PushesOutOfTheCreasesOfTheKickingLeg) {
  const std::shared_ptr<const Avatar> humanoid = MakeHumanoid();
  const Clip kick = MakeBuiltInClip("kick", humanoid->shared_skeleton());
  const Skeleton& skeleton = humanoid->skeleton();
  const std::unique_ptr<SuperquadricCollider> owned = SimulationCollider(humanoid);
  SuperquadricCollider& collider = *owned;
  for (double t : {0.42, 0.825}) {
    std::vector<Eigen::Isometry3d> world;
    const Points skin = PoseAtRest(*humanoid, kick, t, collider, world);
    const MeshDistance truth("humanoid", skin, humanoid->triangles());
    const Eigen::Vector3d hip = world[skeleton.Find(HAnimJoint::kRHip)].translation();
    const Eigen::Vector3d knee = world[skeleton.Find(HAnimJoint::kRKnee)].translation();
    std::vector<Eigen::Vector3d> inside;
    for (int v = 0; v < humanoid->num_vertices(); ++v) {
      const Eigen::Vector3d x = skin.row(v).transpose();
      if ((x - hip).norm() > 0.15 && (x - knee).norm() > 0.15) continue;
      const SurfaceDistance on = truth.Query(x, 0.1);
      if (std::abs(on.signed_distance) > 1e-6) continue;  // buried in another piece
      const Eigen::Vector3d p = x - 0.003 * on.normal;
      if (truth.PenetrationDepth(p, 0.1) > 0.002) inside.push_back(p);
    }
    ASSERT_GT(inside.size(), 300u) << t;
    Points positions = At(inside);
    Points velocities = Points::Zero(positions.rows(), 3);
    collider.ProjectOut(positions, velocities);
    int left_inside = 0;
    for (Eigen::Index i = 0; i < positions.rows(); ++i) {
      if (truth.PenetrationDepth(positions.row(i).transpose(), 0.1) > 0.0) ++left_inside;
    }
    EXPECT_EQ(left_inside, 0) << "t = " << t << " s, of " << positions.rows();
  }
}

// Maps read the skin along rays from their centres, and where skin meets skin in a crease
// they can read a point deeper than it is (docs/collision.md, "Readings checked against the
// skin"): MakeHuman's upper arms and its hips' and waist's joint shells read particles of
// the suit 6–8 mm too deep, up to 15 mm. The built-in humanoid in frames of its walk and
// kick: points 1 and 3 mm outside the true skin (MeshDistance), inside the cloth's
// thickness, within 15 cm of a hip, the waist or a shoulder. ProjectOut must put each on
// the shell: outside the skin, and no farther from it than the thickness and the leeway a
// map's shell has beside the true one (a map's cell is a centimetre wide). Before readings
// were checked against the skin, 11–26 points a pose ended farther, up to 16.6 mm from the
// skin; points 1 to 3 mm beyond the thickness remain (8–20 a pose beyond 2 mm).
TEST(SuperquadricCollider, PointsWithinTheThicknessGoOntoTheShellNotBeyondIt) {
  constexpr double kLeeway = 0.005;  // [m]
  const std::shared_ptr<const Avatar> humanoid = MakeHumanoid();
  const Skeleton& skeleton = humanoid->skeleton();
  const std::unique_ptr<SuperquadricCollider> owned = SimulationCollider(humanoid);
  SuperquadricCollider& collider = *owned;
  const std::vector<int> creases = {
      skeleton.Find(HAnimJoint::kLHip), skeleton.Find(HAnimJoint::kRHip),
      skeleton.Find(HAnimJoint::kSacroiliac), skeleton.Find(HAnimJoint::kLShoulder),
      skeleton.Find(HAnimJoint::kRShoulder)};
  int checked = 0;
  for (const char* name : {"walk", "kick"}) {
    const Clip clip = MakeBuiltInClip(name, humanoid->shared_skeleton());
    for (double t : {0.2, 0.5, 0.8}) {
      std::vector<Eigen::Isometry3d> world;
      const Points skin = PoseAtRest(*humanoid, clip, t, collider, world);
      const MeshDistance truth("humanoid", skin, humanoid->triangles());
      std::vector<Eigen::Vector3d> near;
      for (int v = 0; v < humanoid->num_vertices(); ++v) {
        const Eigen::Vector3d x = skin.row(v).transpose();
        if (std::none_of(creases.begin(), creases.end(), [&](int j) {
              return (x - world[j].translation()).norm() < 0.15;
            })) {
          continue;
        }
        const SurfaceDistance on = truth.Query(x, 0.1);
        if (std::abs(on.signed_distance) > 1e-6) continue;  // buried in another piece
        for (double offset : {0.001, 0.003}) {
          const Eigen::Vector3d p = x + offset * on.normal;
          // Only where the offset is the distance: not across a crease onto other skin.
          if (std::abs(truth.SignedDistance(p, 0.1) - offset) < 1e-4) near.push_back(p);
        }
      }
      ASSERT_GT(near.size(), 1000u) << name << " at " << t << " s";
      Points positions = At(near);
      Points velocities = Points::Zero(positions.rows(), 3);
      collider.ProjectOut(positions, velocities);
      int inside = 0, beyond = 0;
      double farthest = 0.0;
      for (Eigen::Index i = 0; i < positions.rows(); ++i) {
        const Eigen::Vector3d p = positions.row(i).transpose();
        if (truth.PenetrationDepth(p, 0.1) > 0.0) ++inside;
        const double distance = truth.SignedDistance(p, 0.1);
        farthest = std::max(farthest, distance);
        if (distance > kThickness + kLeeway) ++beyond;
      }
      checked += static_cast<int>(positions.rows());
      EXPECT_EQ(inside, 0) << name << " at " << t << " s, of " << positions.rows();
      EXPECT_EQ(beyond, 0) << name << " at " << t << " s, of " << positions.rows()
                           << " beyond " << 1e3 * (kThickness + kLeeway)
                           << " mm; farthest " << 1e3 * farthest << " mm from the skin";
    }
  }
  EXPECT_GT(checked, 9000);
}

// Points deep in a straight limb near its axis (docs/collision.md, "Nodes that saw no
// skin"): seen from the thigh's, the shank's or the knee's centre, they lie on rays that run
// along the leg and leave the skin only at its far end, beyond each shell's reach, so every
// map reads them blind. ProjectOut hands them to the skin triangles themselves, which put
// them on the shell: outside the true skin (MeshDistance) and within a few millimetres of
// it. Before, they stayed where they were (45 mm deep near MakeHuman's kicking knee).
TEST(SuperquadricCollider, PushesPointsDeepInALimbNearItsAxisOutOfIt) {
  const std::shared_ptr<const Avatar> humanoid = MakeHumanoid();
  const Skeleton& skeleton = humanoid->skeleton();
  const std::unique_ptr<SuperquadricCollider> owned = SimulationCollider(humanoid);
  SuperquadricCollider& collider = *owned;
  const std::vector<Eigen::Isometry3d>& world = skeleton.rest_world();
  collider.Update(world, humanoid->rest_vertices(), 0.01);
  collider.Update(world, humanoid->rest_vertices(), 0.01);  // at rest
  const MeshDistance truth("humanoid", humanoid->rest_vertices(), humanoid->triangles());
  const Eigen::Vector3d hip = world[skeleton.Find(HAnimJoint::kRHip)].translation();
  const Eigen::Vector3d knee = world[skeleton.Find(HAnimJoint::kRKnee)].translation();
  const Eigen::Vector3d ankle = world[skeleton.Find(HAnimJoint::kRTalocrural)].translation();
  std::vector<Eigen::Vector3d> deep;
  for (int k = 1; k < 20; ++k) {
    const double f = k / 20.0;
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(hip + f * (knee - hip)),
                                     Eigen::Vector3d(knee + f * (ankle - knee))}) {
      if (truth.PenetrationDepth(p, 0.2) > 0.02) deep.push_back(p);
    }
  }
  ASSERT_GT(deep.size(), 25u);
  Points positions = At(deep);
  Points velocities = Points::Zero(positions.rows(), 3);
  collider.ProjectOut(positions, velocities);
  EXPECT_GT(collider.stats().num_skin_checks, 0);
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    const Eigen::Vector3d x = positions.row(i).transpose();
    const double distance = truth.SignedDistance(x, 0.2);
    EXPECT_EQ(truth.PenetrationDepth(x, 0.2), 0.0) << "point " << i << " of " << positions.rows();
    EXPECT_LE(distance, kThickness + 0.003) << "point " << i << " of " << positions.rows();
  }
}

// Skin moved through other skin (linear blend skinning pushes MakeHuman's kicking thigh
// through its groin): a box beside the capsule, skinned to the same segment, moves half
// into it. From the centre, rays through the box enter it, leave the capsule inside it and
// then leave the box: their first exit is the capsule's wall, inside the box. They are
// followed to the box's outer face (folded rays, docs/collision.md), so points in the box
// outside the capsule, which the first exit put outside the shell, are pushed out of the
// box, the body being the union of the two (MeshDistance's winding number).
TEST(SuperquadricCollider, PushesPointsOutOfSkinMovedThroughOtherSkin) {
  const Eigen::Vector3d half(0.015, 0.03, 0.03);
  const Eigen::Vector3d rest_centre = kCentre + Eigen::Vector3d(kRadius + 0.005 + half.x(), 0, 0);
  const test::TestMesh box = test::TessellatedBox(rest_centre, half, Eigen::Vector3i(3, 6, 6));
  const std::shared_ptr<const Avatar> avatar = MakeCapsuleAvatar({box});
  SuperquadricCollider collider(avatar, BodyCollisionSettings{kThickness, 0.5});
  const std::vector<Eigen::Isometry3d>& world = avatar->skeleton().rest_world();
  const Eigen::Isometry3d arm = world[1];
  // The box's vertices are the last before the five loose ones; 15 mm inwards it spans
  // 40–70 mm from the axis, through the capsule's wall at 50 mm.
  const Eigen::Vector3d inwards = arm.linear() * Eigen::Vector3d(-0.015, 0, 0);
  Points skin = avatar->rest_vertices();
  const Eigen::Index first_box = skin.rows() - 5 - box.vertices.rows();
  for (Eigen::Index v = first_box; v < first_box + box.vertices.rows(); ++v) {
    skin.row(v) += inwards.transpose();
  }
  collider.Update(world, skin, 0.01);
  collider.Update(world, skin, 0.01);  // at rest there
  std::vector<Eigen::Vector3d> local;
  for (double x : {0.056, 0.061, 0.066}) {
    for (double y : {-0.01, 0.0, 0.01}) {
      for (double z : {-0.01, 0.0, 0.01}) {
        local.push_back(kCentre + Eigen::Vector3d(x + 0.0003, y + 0.0007, z - 0.0004));
      }
    }
  }
  Points positions = At(local, arm);
  const MeshDistance truth("capsule and box", skin, avatar->triangles());
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    ASSERT_GT(truth.PenetrationDepth(positions.row(i).transpose(), 0.1), 0.003) << i;
  }
  Points velocities = Points::Zero(positions.rows(), 3);
  collider.ProjectOut(positions, velocities);
  const Eigen::Isometry3d to_arm = arm.inverse();
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    const Eigen::Vector3d x = positions.row(i).transpose();
    EXPECT_EQ(truth.PenetrationDepth(x, 0.1), 0.0) << "point " << i;
    // Onto the shell over the box's outer face, 70 mm from the axis.
    EXPECT_NEAR((to_arm * x - kCentre).x(), 0.070 + kThickness, 0.001) << "point " << i;
  }
}

// Skin skinned through skin of the same piece (a running knee bends MakeHuman's calf
// through the back of its thigh; docs/collision.md, "Skin through skin, counted"): one
// closed bar, its upper half a thigh and its lower half a calf, bent 150° at the knee, so
// linear blend skinning folds each half into the other. Points more than a thickness inside
// the body by its winding number (MeshDistance) whose nearest skin is buried skin facing
// them are all pushed out of the body. The nearest point's sign alone put them outside and
// left 1,496 of 1,596 in, up to 38 mm deep. (Shallower ones in the crease behind the knee
// are pinched between the two shells, as in APinchedParticleEndsNoDeeperThanItStarted.)
// The body is also turned as a whole by 1e-13 and 3e-12 rad, which changes nothing but
// rounding: there the knee's shell read one point 6.7 mm inside the body 31 µm inside its
// shell, and the pushes out of it alone left the point where it was, until deeper uncertain
// readings were taken to the skin too (docs/collision.md, "A certain reading that hid
// deeper ones").
TEST(SuperquadricCollider, PushesPointsOutOfSkinFoldedThroughItsOwnPiece) {
  constexpr double kKneeHeight = 0.8, kHalfBar = 0.2, kHalfWidth = 0.04, kBlend = 0.02;
  std::vector<Joint> joints(2);
  joints[0].name = "thigh";
  joints[0].hanim = HAnimJoint::kLHip;
  joints[0].rest_local = Eigen::Translation3d(0.0, kKneeHeight + kHalfBar, 0.0);
  joints[1].name = "calf";
  joints[1].parent = 0;
  joints[1].hanim = HAnimJoint::kLKnee;
  joints[1].rest_local = Eigen::Translation3d(0.0, -kHalfBar, 0.0);
  AvatarData data;
  data.name = "bent bar";
  data.skeleton = Skeleton::Create("bent bar", joints);
  const test::TestMesh bar =
      test::TessellatedBox(Eigen::Vector3d(0.0, kKneeHeight, 0.0),
                           Eigen::Vector3d(kHalfWidth, kHalfBar, kHalfWidth),
                           Eigen::Vector3i(4, 40, 4));
  data.rest_vertices = bar.vertices;
  data.triangles = bar.triangles;
  const Eigen::Index n = bar.vertices.rows();
  data.influence_joints.setConstant(n, kMaxInfluences, -1);
  data.influence_weights.setZero(n, kMaxInfluences);
  for (Eigen::Index v = 0; v < n; ++v) {
    // Linear across a band at the knee, as skinning weights are painted.
    const double calf =
        std::clamp(0.5 - (bar.vertices(v, 1) - kKneeHeight) / (2.0 * kBlend), 0.0, 1.0);
    data.influence_joints(v, 0) = 0;
    data.influence_weights(v, 0) = 1.0 - calf;
    data.influence_joints(v, 1) = 1;
    data.influence_weights(v, 1) = calf;
  }
  const std::shared_ptr<const Avatar> avatar = Avatar::Create(std::move(data));
  for (double turn : {0.0, 1e-13, 3e-12}) {
    std::vector<Eigen::Isometry3d> world = avatar->skeleton().rest_world();
    world[1] = world[1] * Eigen::AngleAxisd(150.0 * std::numbers::pi / 180.0,
                                            Eigen::Vector3d::UnitX());
    for (Eigen::Isometry3d& joint : world) {
      joint = Eigen::AngleAxisd(turn, Eigen::Vector3d(0.3, 0.5, 0.8).normalized()) * joint;
    }
    std::vector<Eigen::Isometry3d> skinning;
    Points skin;
    SkinVertices(*avatar, world, skinning, skin);
    const std::unique_ptr<SuperquadricCollider> owned = SimulationCollider(avatar);
    SuperquadricCollider& collider = *owned;
    ASSERT_EQ(collider.segments().size(), 3u);  // thigh, calf and the knee's joint shell
    collider.Update(world, skin, 0.01);
    collider.Update(world, skin, 0.01);  // at rest in this pose
    const MeshDistance truth("bent bar", skin, avatar->triangles());
    std::vector<Eigen::Vector3d> buried;
    for (double x = -0.03; x <= 0.031; x += 0.01) {
      for (double y = kKneeHeight - 0.02; y <= kKneeHeight + 0.2; y += 0.004) {
        for (double z = -0.2; z <= 0.2; z += 0.004) {
          const Eigen::Vector3d p(x + 1.3e-4, y + 2.9e-4, z + 0.7e-4);
          if (truth.PenetrationDepth(p, 0.1) > 0.005 && truth.SignedDistance(p, 0.1) > 0.0) {
            buried.push_back(p);
          }
        }
      }
    }
    ASSERT_GT(buried.size(), 50u);
    Points positions = At(buried);
    Points velocities = Points::Zero(positions.rows(), 3);
    collider.ProjectOut(positions, velocities);
    EXPECT_GT(collider.stats().num_buried, 0);
    int left_inside = 0;
    double deepest_left = 0.0;
    for (Eigen::Index i = 0; i < positions.rows(); ++i) {
      const double depth = truth.PenetrationDepth(positions.row(i).transpose(), 0.1);
      if (depth > 0.0) ++left_inside;
      deepest_left = std::max(deepest_left, depth);
    }
    EXPECT_EQ(left_inside, 0) << "turned " << turn << " rad: of " << positions.rows()
                              << ", the deepest " << 1e3 * deepest_left << " mm in";
  }
}

/// Two capsules (each as MakeCapsuleAvatar's, rigid on its own hip joint under the root)
/// whose joints stand at x = ±`offset`, y = 1 m, the left turned by −`tilt` and the right
/// by +`tilt` [rad] about z, so that at tilt > 0 their axes close in going down: a crease
/// opening upwards. `frames` gets each capsule's joint frame (for CapsuleDistance).
std::shared_ptr<const Avatar> TwoCapsules(double offset, double tilt,
                                          std::array<Eigen::Isometry3d, 2>& frames) {
  std::vector<Joint> joints(3);
  joints[0].name = "root";
  joints[0].hanim = HAnimJoint::kHumanoidRoot;
  for (int side = 1; side <= 2; ++side) {
    const double sign = side == 1 ? 1.0 : -1.0;
    joints[side].name = side == 1 ? "left" : "right";
    joints[side].parent = 0;
    joints[side].hanim = side == 1 ? HAnimJoint::kLHip : HAnimJoint::kRHip;
    joints[side].rest_local = Eigen::Translation3d(sign * offset, 1.0, 0.0) *
                              Eigen::AngleAxisd(-sign * tilt, Eigen::Vector3d::UnitZ());
  }
  AvatarData data;
  data.name = "two capsules";
  data.skeleton = Skeleton::Create("two capsules", joints);
  std::vector<Eigen::Vector3d> world;
  std::vector<int> owner;
  for (int side = 1; side <= 2; ++side) {
    frames[side - 1] = data.skeleton->rest_world()[side];
    // Numbered from 0 in `local`, from `first` in the avatar.
    std::vector<Eigen::Vector3d> local;
    const std::size_t first_triangle = data.triangles.size();
    AppendCapsule(kCentre, local, data.triangles);
    const int first = static_cast<int>(world.size());
    for (std::size_t t = first_triangle; t < data.triangles.size(); ++t) {
      data.triangles[t] += Eigen::Vector3i::Constant(first);
    }
    for (const Eigen::Vector3d& p : local) {
      world.push_back(frames[side - 1] * p);
      owner.push_back(side);
    }
  }
  for (int v = 0; v < 5; ++v) {
    world.push_back(Eigen::Vector3d(0.01 * v, 1.2, 0.0));
    owner.push_back(0);
  }
  const Eigen::Index n = static_cast<Eigen::Index>(world.size());
  data.rest_vertices.resize(n, 3);
  data.influence_joints.setConstant(n, kMaxInfluences, -1);
  data.influence_weights.setZero(n, kMaxInfluences);
  for (Eigen::Index v = 0; v < n; ++v) {
    data.rest_vertices.row(v) = world[v].transpose();
    data.influence_joints(v, 0) = owner[v];
    data.influence_weights(v, 0) = 1.0;
  }
  return Avatar::Create(std::move(data));
}

/// Distance of `x` (world) from the nearer skin of the capsules in `frames` [m] (closed
/// form).
double NearerCapsuleDistance(const std::array<Eigen::Isometry3d, 2>& frames,
                             const Eigen::Vector3d& x) {
  return std::min(CapsuleDistance(frames[0].inverse() * x),
                  CapsuleDistance(frames[1].inverse() * x));
}

/// A collider of `avatar` (the tests' thickness) at rest in its rest pose.
std::unique_ptr<SuperquadricCollider> RestingCollider(std::shared_ptr<const Avatar> avatar) {
  auto collider =
      std::make_unique<SuperquadricCollider>(avatar, BodyCollisionSettings{kThickness, 0.5});
  collider->Update(avatar->skeleton().rest_world(), avatar->rest_vertices(), 0.01);
  collider->Update(avatar->skeleton().rest_world(), avatar->rest_vertices(), 0.01);
  return collider;
}

/// `start` after ProjectOut alone.
Eigen::Vector3d ProjectedAlone(SuperquadricCollider& collider, const Eigen::Vector3d& start) {
  Points positions(1, 3);
  positions.row(0) = start.transpose();
  Points velocities = Points::Zero(1, 3);
  collider.ProjectOut(positions, velocities);
  return positions.row(0).transpose();
}

/// `start` after ProjectOut alone between two parallel upright capsules `gap` [m] apart,
/// skin to skin, on either side of x = 0 (TwoCapsules); `frames` gets their joint frames.
Eigen::Vector3d ProjectedBetweenParallelCapsules(double gap, const Eigen::Vector3d& start,
                                                 std::array<Eigen::Isometry3d, 2>& frames) {
  const std::shared_ptr<const Avatar> avatar = TwoCapsules(kRadius + 0.5 * gap, 0.0, frames);
  const std::unique_ptr<SuperquadricCollider> collider = RestingCollider(avatar);
  EXPECT_EQ(collider->segments().size(), 2u);
  return ProjectedAlone(*collider, start);
}

// Two limbs closer than two cloth thicknesses pinch a particle between their shells (the
// thighs at MakeHuman's crotch): each push out of one shell is into the other, and the
// passes throw it back and forth. Two parallel capsules 6 mm apart (hips under an unfitted
// root) and a particle in the gap, 2.8 and 3.2 mm from their skins, 1.2 and 0.8 mm inside
// their shells (closed form): every push leaves it 2 mm inside the other shell, so when
// the passes run out it goes where it is least deep, midway (3 mm from each skin).
TEST(SuperquadricCollider, APinchedParticleEndsNoDeeperThanItStarted) {
  std::array<Eigen::Isometry3d, 2> frames;
  const Eigen::Vector3d start(0.0002, 0.853, 0.001);
  const Eigen::Vector3d end = ProjectedBetweenParallelCapsules(0.006, start, frames);
  ASSERT_NEAR(NearerCapsuleDistance(frames, start), 0.0028, 2e-5);
  // Without going back it ended 2 mm from one skin, 2 mm inside that shell.
  EXPECT_GE(NearerCapsuleDistance(frames, end), 0.0027);
}

// Skins closer than one thickness (an arm against the torso, 0.5 mm at the suit's armpit
// in collision_bench --self-collision): each push out of one shell leaves the particle
// inside the other skin. Two parallel capsules 1 mm apart and a particle 2 mm inside one of
// them, between the two: every push leaves it 3 mm inside the other skin, as did going
// back to the least deep place it went through (the suit's particle 1040: 3.5 mm). Midway
// it is 0.5 mm from each skin (closed form).
TEST(SuperquadricCollider, AParticlePinchedBetweenSkinsCloserThanAThicknessGoesMidway) {
  std::array<Eigen::Isometry3d, 2> frames;
  const Eigen::Vector3d start(0.0025, 0.853, 0.001);
  const Eigen::Vector3d end = ProjectedBetweenParallelCapsules(0.001, start, frames);
  ASSERT_NEAR(NearerCapsuleDistance(frames, start), -0.002, 2e-5);
  EXPECT_NEAR(CapsuleDistance(frames[0].inverse() * end), 0.0005, 2e-4) << end.transpose();
  EXPECT_NEAR(CapsuleDistance(frames[1].inverse() * end), 0.0005, 2e-4) << end.transpose();
}

// Where the two walls close in on one side (an arm swinging against the chest, the thighs
// under the groin), a pinched particle has a way out: along the crease to where it opens
// (EscapePinch). Two capsules tilted 10° towards each other below their joints, and a
// particle at their middles 2.8 mm from each skin (closed form), 1.2 mm inside both shells;
// eight passes lift it by under 2 mm, where the walls still stand closer than two
// thicknesses. It must end above, outside both shells. Going back to the least deep place
// it went through, it ended 2.8 mm from the skins.
TEST(SuperquadricCollider, AParticlePinchedInAClosingCreaseLeavesWhereItOpens) {
  constexpr double kTilt = 10.0 * kPi / 180.0;
  constexpr double kGap = 0.0028;  // the particle's distance from each skin [m]
  // The joint's offset that puts each tilted axis kRadius + kGap from the point below the
  // joints at the capsules' middles (0.15 m down their axes).
  const double offset = (kRadius + kGap + 0.15 * std::sin(kTilt)) / std::cos(kTilt);
  std::array<Eigen::Isometry3d, 2> frames;
  const std::shared_ptr<const Avatar> avatar = TwoCapsules(offset, kTilt, frames);
  const std::unique_ptr<SuperquadricCollider> collider = RestingCollider(avatar);
  ASSERT_EQ(collider->segments().size(), 2u);
  const Eigen::Vector3d start(0.0, 1.0 - 0.15, 0.001);
  ASSERT_NEAR(CapsuleDistance(frames[0].inverse() * start), kGap, 2e-5);
  ASSERT_NEAR(CapsuleDistance(frames[1].inverse() * start), kGap, 2e-5);
  const Eigen::Vector3d end = ProjectedAlone(*collider, start);
  EXPECT_GE(NearerCapsuleDistance(frames, end), kThickness - 3e-4)
      << "ended at " << end.transpose();
  EXPECT_GT(end.y(), start.y() + 0.002);  // up, where the crease opens
  EXPECT_LT((end - start).norm(), 0.03);
}

TEST(SuperquadricCollider, RefusesBadInput) {
  EXPECT_THROW(SuperquadricCollider(nullptr), InputError);
  BodyCollisionSettings settings;
  settings.thickness = -1.0;
  EXPECT_THROW(SuperquadricCollider(MakeCapsuleAvatar(), settings), InputError);
  SuperquadricColliderOptions options;
  options.map_spacing = 0.001;  // below 2 mm
  EXPECT_THROW(SuperquadricCollider(MakeCapsuleAvatar(), {}, options), InputError);
  options = {};
  options.map_cache_quantum = 0.0;
  EXPECT_THROW(SuperquadricCollider(MakeCapsuleAvatar(), {}, options), InputError);
}

}  // namespace
}  // namespace costume::sim
