// Self-collision: proximity repulsion keeps the thickness and conserves momentum, continuous
// detection stops what proximity alone misses, and a folded napkin dropped on a sphere ends
// without one edge through the cloth (and does not without self-collision).
#include "sim_core/collision/self_collision.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <initializer_list>
#include <new>
#include <set>

#include "sim_core/cloth/lattice_panel.h"
#include "sim_core/cloth/material.h"
#include "sim_core/collision/sphere_contacts.h"
#include "sim_core/solver/implicit_stepper.h"
#include "sim_core/solver/strain_limit.h"

// Counts operator-new allocations (std::vector growth) so a test can check that a repeated
// Resolve allocates nothing. Eigen and Bullet call malloc directly and are not counted; their
// buffers (path velocities, boxes, the tree's stack) are sized once by construction.
namespace {
std::size_t g_allocations = 0;
}  // namespace
void* operator new(std::size_t size) {
  ++g_allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
// GCC cannot see that the replaced operator new above returns malloc'd memory.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop

namespace costume::sim {
namespace {

using Vec3 = Eigen::Vector3d;

/// Two equilateral triangles without a shared particle, centred on the y axis: A = particles
/// 0–2 in the plane y = 0, circumradius 0.2 m (mass `mass_a` each); B = particles 3–5, the same
/// shape scaled to 0.03 m at height `gap` (mass `mass_b` each), so B lies well inside A's
/// outline and, by symmetry, anything B does to A pushes A's three particles alike.
std::shared_ptr<const ClothModel> TwoTriangles(double gap, double mass_a, double mass_b) {
  ClothModelData data;
  data.name = "two triangles";
  data.rest_positions.resize(6, 3);
  for (int k = 0; k < 3; ++k) {
    const double angle = 2.0 * M_PI * k / 3.0;
    data.rest_positions.row(k) << 0.2 * std::sin(angle), 0.0, 0.2 * std::cos(angle);
    data.rest_positions.row(3 + k) << 0.03 * std::sin(angle), gap, 0.03 * std::cos(angle);
  }
  data.masses.resize(6);
  data.masses << mass_a, mass_a, mass_a, mass_b, mass_b, mass_b;
  data.areas = Eigen::VectorXd::Zero(6);
  data.triangles = {Eigen::Vector3i(0, 1, 2), Eigen::Vector3i(3, 4, 5)};
  return ClothModel::Create(data);
}

Vec3 Momentum(const ClothModel& model, const Points& velocities) {
  return (velocities.transpose() * model.masses());
}

/// Height above A's plane (particles 0–2, normal taken upwards) of the lowest of particles
/// first..first+2 at `x`: B's by default.
double LowestHeightOfBAboveA(const Points& x, int first = 3) {
  const Vec3 a = x.row(0), b = x.row(1), c = x.row(2);
  Vec3 n = (b - a).cross(c - a).normalized();
  if (n.y() < 0.0) n = -n;
  double lowest = 1e9;
  for (int i = first; i < first + 3; ++i) lowest = std::min(lowest, (Vec3(x.row(i)) - a).dot(n));
  return lowest;
}

/// What Resolve receives after a step of length h from `model`'s rest positions with the
/// particles' vertical velocities `vy` [m/s] (nothing else moving): the state at the end of
/// the step on the straight path.
ClothState EndOfStraightStep(const ClothModel& model, double h, std::initializer_list<double> vy) {
  ClothState state = ClothState::AtRest(model);
  int i = 0;
  for (double v : vy) state.velocities(i++, 1) = v;
  state.positions = model.rest_positions() + h * state.velocities;
  return state;
}

TEST(SelfCollision, HeadOnTrianglesEndAtLeastTheThicknessApartKeepingMomentum) {
  const double gap = 0.003, h = 1.0 / 240.0, mass_a = 1e-3, mass_b = 2e-3;
  const auto model = TwoTriangles(gap, mass_a, mass_b);
  SelfCollisionSettings settings;  // thickness 4 mm > gap
  SelfCollision self_collision(model, settings);
  const Points start = model->rest_positions();
  // A rises at 1 m/s, B falls at 1 m/s: unresolved they pass through each other this step.
  ClothState state = EndOfStraightStep(*model, h, {1, 1, 1, -1, -1, -1});
  ASSERT_LT(LowestHeightOfBAboveA(state.positions), 0.0);

  const SelfCollisionReport report = self_collision.Resolve(start, h, state);

  EXPECT_FALSE(report.skipped);
  EXPECT_GT(report.proximity_impulses, 0);
  EXPECT_EQ(report.remaining_collisions, 0);
  EXPECT_GE(LowestHeightOfBAboveA(state.positions), settings.thickness);
  EXPECT_EQ(CountCrossingEdges(*model, state.positions), 0);
  // Momentum by hand: 3·1 g·(+1 m/s) + 3·2 g·(−1 m/s) = −3e-3 kg·m/s along y, none across.
  const Vec3 momentum = Momentum(*model, state.velocities);
  EXPECT_NEAR(momentum.y(), -3e-3, 1e-15);
  EXPECT_NEAR(momentum.x(), 0.0, 1e-15);
  EXPECT_NEAR(momentum.z(), 0.0, 1e-15);
  // The push-out moves positions only, mass-weighted about the centre of mass: the centre
  // moves as the momentum says, h·(−3e-3 kg·m/s)/(9e-3 kg) = −h/3 along y.
  const double total_mass = 3 * mass_a + 3 * mass_b;
  const Vec3 centre_shift =
      ((state.positions - start).transpose() * model->masses()) / total_mass;
  EXPECT_NEAR(centre_shift.y(), -h / 3.0, 1e-13);
  EXPECT_NEAR(centre_shift.x(), 0.0, 1e-13);
  // Fully inelastic and symmetric: every particle ends with the common velocity p/M =
  // −3e-3 / 9e-3 = −1/3 m/s along y (to the sweeps' tolerance).
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(state.velocities(i, 1), -1.0 / 3.0, 1e-5) << "particle " << i;
  }
  const double kinetic_before = 0.5 * total_mass * 1.0;  // every particle at 1 m/s
  const double kinetic_after =
      0.5 * (state.velocities.rowwise().squaredNorm().transpose() * model->masses())(0);
  EXPECT_LT(kinetic_after, kinetic_before);
}

TEST(SelfCollision, ContinuousDetectionStopsAFastParticleProximityMisses) {
  const double h = 1.0 / 240.0;
  const auto model = TwoTriangles(0.05, 1e-3, 1e-3);
  SelfCollision self_collision(model, SelfCollisionSettings{});
  const Points start = model->rest_positions();
  // Particle 3 falls at 20 m/s: 83 mm in one step, from 50 mm above A to 33 mm below it,
  // farther than the 4 mm thickness from A at both ends of the step.
  ClothState state = EndOfStraightStep(*model, h, {0, 0, 0, -20, 0, 0});
  ASSERT_EQ(CountCrossingEdges(*model, state.positions), 2);  // edges 3–4 and 3–5

  const SelfCollisionReport report = self_collision.Resolve(start, h, state);

  EXPECT_EQ(report.proximity_impulses, 0);  // proximity alone saw nothing
  EXPECT_GE(report.collision_impulses, 1);
  EXPECT_EQ(report.remaining_collisions, 0);
  EXPECT_EQ(CountCrossingEdges(*model, state.positions), 0);
  EXPECT_GT(LowestHeightOfBAboveA(state.positions), 0.0);
  // Momentum by hand: 1 g at −20 m/s.
  const Vec3 momentum = Momentum(*model, state.velocities);
  EXPECT_NEAR(momentum.y(), -0.02, 1e-14);
  EXPECT_NEAR(momentum.x(), 0.0, 1e-14);
  EXPECT_NEAR(momentum.z(), 0.0, 1e-14);
}

/// Three triangles of 1 g particles: A (0–2) as TwoTriangles' in the plane y = 0, B (3–5)
/// at `b` (rows), and C (6–8), B's shape scaled to 0.03 m and centred 60 mm beside A's
/// centre along x at height `c_height`: well inside A's outline (its inscribed radius is
/// 0.1 m) and 8 mm clear across of a B of that shape at the centre.
std::shared_ptr<const ClothModel> ThreeTriangles(const std::string& name, const Points& b,
                                                 double c_height) {
  ClothModelData data;
  data.name = name;
  data.rest_positions.resize(9, 3);
  for (int k = 0; k < 3; ++k) {
    const double s = std::sin(2.0 * M_PI * k / 3.0), c = std::cos(2.0 * M_PI * k / 3.0);
    data.rest_positions.row(k) << 0.2 * s, 0.0, 0.2 * c;
    data.rest_positions.row(6 + k) << 0.06 + 0.03 * s, c_height, 0.03 * c;
  }
  data.rest_positions.middleRows(3, 3) = b;
  data.masses = Eigen::VectorXd::Constant(9, 1e-3);
  data.areas = Eigen::VectorXd::Zero(9);
  data.triangles = {Eigen::Vector3i(0, 1, 2), Eigen::Vector3i(3, 4, 5), Eigen::Vector3i(6, 7, 8)};
  return ClothModel::Create(data);
}

/// ThreeTriangles with TwoTriangles(0.003, …)'s B, 3 mm above A (within the thickness),
/// and C 50 mm above A.
std::shared_ptr<const ClothModel> BRestingAndCFalling() {
  const Points b = TwoTriangles(0.003, 1e-3, 1e-3)->rest_positions().bottomRows(3);
  return ThreeTriangles("B resting, C falling", b, 0.05);
}

/// What a moving-only resolve of BRestingAndCFalling's step must report and leave: particle
/// 6 stopped by continuous detection alone, no proximity impulse, nothing crossing.
void ExpectStoppedByDetectionAlone(const SelfCollisionReport& report, const ClothModel& model,
                                   const ClothState& state) {
  EXPECT_FALSE(report.skipped);
  EXPECT_EQ(report.proximity_impulses, 0);
  EXPECT_GE(report.collision_impulses, 1);
  EXPECT_EQ(report.remaining_collisions, 0);
  EXPECT_EQ(CountCrossingEdges(model, state.positions), 0);
}

// After a step Resolve made collision-free, the body's correction moves a few particles;
// ResolveMove makes that move collision-free too, examining only what moves. Here C's
// particle 6 falls through A at 20 m/s while B rests 3 mm above A, within the thickness:
// ResolveMove stops particle 6 and leaves B exactly where it was; Resolve, the control,
// also pushes B out to the thickness.
TEST(SelfCollision, ResolveMoveStopsWhatMovesAndLeavesPairsAtRest) {
  const double h = 1.0 / 240.0;
  const auto model = BRestingAndCFalling();
  SelfCollisionSettings settings;
  SelfCollision self_collision(model, settings);
  const Points start = model->rest_positions();
  const ClothState input = EndOfStraightStep(*model, h, {0, 0, 0, 0, 0, 0, -20, 0, 0});
  ASSERT_EQ(CountCrossingEdges(*model, input.positions), 2);  // edges 6–7 and 6–8

  ClothState moved = input;
  ExpectStoppedByDetectionAlone(self_collision.ResolveMove(start, h, moved), *model, moved);
  EXPECT_TRUE(moved.positions.middleRows(3, 3) == start.middleRows(3, 3));  // B untouched
  // Momentum by hand: 1 g at −20 m/s.
  EXPECT_NEAR(Momentum(*model, moved.velocities).y(), -0.02, 1e-14);

  ClothState resolved = input;
  self_collision.Resolve(start, h, resolved);
  EXPECT_EQ(CountCrossingEdges(*model, resolved.positions), 0);
  EXPECT_GE(LowestHeightOfBAboveA(resolved.positions), settings.thickness);
}

// The strain limit after Resolve shortens springs; ResolveCrossings makes that move
// crossing-free without the proximity stage, whose push-out to the thickness would stretch
// them again. Here B, resting 3 mm above A, moves 1 mm down (to 2 mm, within the 4 mm
// thickness) while C's particle 6 falls through A at 20 m/s: ResolveCrossings stops particle
// 6 and leaves B where the move put it; ResolveMove, the control, also keeps B off A.
TEST(SelfCollision, ResolveCrossingsStopsCrossingsAndPushesNothingApart) {
  const double h = 1.0 / 240.0;
  const auto model = BRestingAndCFalling();
  SelfCollision self_collision(model, SelfCollisionSettings{});
  const Points start = model->rest_positions();
  const double down = 0.001 / h;  // B's speed [m/s]: 1 mm in the step
  const ClothState input =
      EndOfStraightStep(*model, h, {0, 0, 0, -down, -down, -down, -20, 0, 0});
  ASSERT_EQ(CountCrossingEdges(*model, input.positions), 2);  // edges 6–7 and 6–8
  ASSERT_NEAR(LowestHeightOfBAboveA(input.positions), 0.002, 1e-12);

  ClothState crossings = input;
  ExpectStoppedByDetectionAlone(self_collision.ResolveCrossings(start, h, crossings), *model,
                                crossings);
  EXPECT_TRUE(crossings.positions.middleRows(3, 3) == input.positions.middleRows(3, 3));
  // Momentum by hand: 1 g at −20 m/s and 3 g at −0.24 m/s.
  EXPECT_NEAR(Momentum(*model, crossings.velocities).y(), -0.02 - 3e-3 * down, 1e-14);

  ClothState moved = input;
  self_collision.ResolveMove(start, h, moved);
  EXPECT_EQ(CountCrossingEdges(*model, moved.positions), 0);
  EXPECT_GT(LowestHeightOfBAboveA(moved.positions), 0.0025);  // its approach stopped
}

// A particle falling at 20 m/s through two layers, B 10 mm above A (farther apart than the
// thickness, so proximity sees nothing): stopping it on B sets B moving down through A, a
// collision that the first pass examined before it existed. Later passes examine only the
// pairs whose paths the earlier ones changed; they must still find it.
TEST(SelfCollision, LaterPassesFindTheCollisionAnEarlierImpulseMade) {
  const double h = 1.0 / 240.0;
  Points b = TwoTriangles(0.0, 1e-3, 1e-3)->rest_positions().topRows(3);  // A's shape
  b.col(1).setConstant(0.01);
  const auto model = ThreeTriangles("two layers and a falling particle", b, 0.05);
  SelfCollision self_collision(model, SelfCollisionSettings{});
  const Points start = model->rest_positions();
  ClothState state = EndOfStraightStep(*model, h, {0, 0, 0, 0, 0, 0, -20, 0, 0});
  ASSERT_EQ(CountCrossingEdges(*model, state.positions), 2);  // edges 6–7 and 6–8

  const SelfCollisionReport report = self_collision.Resolve(start, h, state);

  EXPECT_EQ(report.proximity_impulses, 0);
  EXPECT_GE(report.collision_passes, 2);
  EXPECT_EQ(report.remaining_collisions, 0);
  EXPECT_EQ(CountCrossingEdges(*model, state.positions), 0);
  EXPECT_GT(LowestHeightOfBAboveA(state.positions), 0.0);  // B still above A
  // Momentum by hand: 1 g at −20 m/s.
  EXPECT_NEAR(Momentum(*model, state.velocities).y(), -0.02, 1e-14);
}

/// ThreeTriangles with B standing through A's middle, its tip 2 mm above A and its base
/// 2 mm below (all three corners within the thickness of A), so that its two slanted edges
/// pass through A in the rest shape; C lies flat 3 mm above A, within the thickness.
std::shared_ptr<const ClothModel> PiercedTriangle() {
  Points b(3, 3);
  b << 0.0, 0.002, 0.0, -0.02, -0.002, 0.0, 0.02, -0.002, 0.0;
  return ThreeTriangles("pierced triangle", b, 0.003);
}

// A garment modelled passing through itself (the MakeHuman casual suit: 38 edges through
// it at rest) cannot be kept on the side it started on. Resting as modelled, the pierced
// pair (A, B) is left as it is, while C, 3 mm above A and not tangled with it, is still
// pushed out to the thickness.
TEST(SelfCollision, LeavesAPairThatCrossesAtRestAsModelled) {
  const double h = 1.0 / 240.0;
  const auto model = PiercedTriangle();
  ASSERT_EQ(CountCrossingEdges(*model, model->rest_positions()), 2);  // edges 3–4 and 3–5
  SelfCollisionSettings settings;
  SelfCollision self_collision(model, settings);
  EXPECT_EQ(self_collision.num_rest_tangled_triangles(), 2);  // A and B; C shares no edge
  const Points start = model->rest_positions();
  ClothState state = ClothState::AtRest(*model);

  const SelfCollisionReport report = self_collision.Resolve(start, h, state);

  EXPECT_EQ(report.remaining_collisions, 0);
  EXPECT_TRUE(state.positions.middleRows(3, 3) == start.middleRows(3, 3));  // B as modelled
  EXPECT_EQ(CountCrossingEdges(*model, state.positions), 2);
  EXPECT_GE(LowestHeightOfBAboveA(state.positions, /*first=*/6), settings.thickness);  // C
}

/// Triangle A (particles 0–2) held by a body below it: its normal out of the body is +y.
std::vector<BodyHold> HoldA() {
  std::vector<BodyHold> holds;
  for (int i = 0; i < 3; ++i) holds.push_back({i, Vec3::UnitY()});
  return holds;
}

// A layer lying on the body, with another falling onto it: the body (infinitely heavy)
// takes the blow, so the held layer stays where it was and the falling one stops on it
// (inelastic: B's normal velocity becomes the body's, 0). Without the hold the same blow
// is shared by momentum and pushes A down, towards the body.
TEST(SelfCollision, BodyHeldLayerStaysWhileTheFallingLayerStopsOnIt) {
  const double gap = 0.003, h = 1.0 / 240.0;
  const auto model = TwoTriangles(gap, 1e-3, 2e-3);
  SelfCollisionSettings settings;  // thickness 4 mm > gap
  const Points start = model->rest_positions();
  const ClothState falling = EndOfStraightStep(*model, h, {0, 0, 0, -1, -1, -1});  // B falls

  ClothState shared = falling;
  SelfCollision(model, settings).Resolve(start, h, shared);
  ClothState held = falling;
  const SelfCollisionReport report =
      SelfCollision(model, settings).Resolve(start, h, held, HoldA());

  // Shared by momentum: A and B end at (3·2 g·(−1 m/s))/(9 g) = −2/3 m/s, A pushed down.
  EXPECT_NEAR(shared.velocities(0, 1), -2.0 / 3.0, 1e-5);
  EXPECT_LT(shared.positions(0, 1), -1e-3);
  EXPECT_EQ(report.remaining_collisions, 0);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(held.positions(i, 1), start(i, 1), 1e-12) << "particle " << i;
    EXPECT_NEAR(held.velocities(i, 1), 0.0, 1e-12) << "particle " << i;
  }
  // B to the sweeps' convergence: each sweep's push on A is taken back by the hold, so B
  // gains a fixed fraction of what is left (16 sweeps: within 1 µm and 1e-4 m/s).
  for (int i = 3; i < 6; ++i) EXPECT_NEAR(held.velocities(i, 1), 0.0, 1e-4) << "particle " << i;
  EXPECT_GT(LowestHeightOfBAboveA(held.positions), settings.thickness - 1e-6);
}

// The same through continuous detection: a particle falling through the held triangle in
// one step stops on it, and the triangle does not move.
TEST(SelfCollision, ContinuousDetectionStopsAFastParticleOnABodyHeldTriangle) {
  const double h = 1.0 / 240.0;
  const auto model = TwoTriangles(0.05, 1e-3, 1e-3);
  SelfCollision self_collision(model, SelfCollisionSettings{});
  const Points start = model->rest_positions();
  // Particle 3 falls at 20 m/s: 83 mm in the step, through A.
  ClothState state = EndOfStraightStep(*model, h, {0, 0, 0, -20, 0, 0});

  const SelfCollisionReport report = self_collision.Resolve(start, h, state, HoldA());

  EXPECT_EQ(report.proximity_impulses, 0);
  EXPECT_GE(report.collision_impulses, 1);
  EXPECT_EQ(report.zone_particles, 0);
  EXPECT_EQ(report.remaining_collisions, 0);
  EXPECT_EQ(CountCrossingEdges(*model, state.positions), 0);
  EXPECT_GT(LowestHeightOfBAboveA(state.positions), 0.0);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(state.positions.row(i), start.row(i)) << "particle " << i;
    EXPECT_EQ(state.velocities.row(i).norm(), 0.0) << "particle " << i;
  }
  EXPECT_NEAR(state.velocities(3, 1), 0.0, 1e-9);  // stopped: the body took its momentum
}

TEST(CountCrossingEdges, CountsAnEdgeThroughATriangleOnceAndIgnoresNeighbours) {
  // A flat lattice has no crossings (neighbours share particles or lie beside each other).
  LatticePanel panel;
  panel.cols = panel.rows = 5;
  const auto flat = ClothModel::Create(BuildLatticePanel(panel, Material{}, "flat"));
  EXPECT_EQ(CountCrossingEdges(*flat, flat->rest_positions()), 0);
  // One particle of B pushed straight through A's interior: its two edges cross A.
  const auto model = TwoTriangles(0.01, 1e-3, 1e-3);
  Points x = model->rest_positions();
  x(3, 1) = -0.01;
  EXPECT_EQ(CountCrossingEdges(*model, x), 2);
  x(3, 1) = 0.0;  // touching A's plane only: not a crossing
  EXPECT_EQ(CountCrossingEdges(*model, x), 0);
}

// A lattice column running on past a triangle's edge lies in that triangle's plane; the
// rounding of its orientation tests must not make it a crossing. The points p, q, a, b are
// x0 + k·d, k = 0..3 (the skirt's rest shape has such columns; these digits were found by
// a search in which the unguarded test counted edge p–q through triangle a–b–c).
TEST(CountCrossingEdges, IgnoresAnEdgeInATrianglesPlaneAlongTheLineOfItsSide) {
  const Vec3 x0(0.15439902292067226, 0.86009769557969407, 0.0059251672513549545);
  const Vec3 d(0.0081168759520836107, -0.031546834309344268, 0.00013314990911424563);
  const Vec3 c(0.17944954072456781, 0.76545719265166123, -0.014313952255833522);
  ClothModelData data;
  data.name = "column past a triangle";
  data.rest_positions.resize(6, 3);
  data.rest_positions.row(0) = x0;
  data.rest_positions.row(1) = x0 + d;
  data.rest_positions.row(2) = x0 + 2.0 * d;
  data.rest_positions.row(3) = x0 + 3.0 * d;
  data.rest_positions.row(4) = c;
  data.rest_positions.row(5) = x0 + Vec3(-0.019, 0.0, 0.0);  // edge p–q's own triangle
  data.masses = Eigen::VectorXd::Constant(6, 1e-3);
  data.areas = Eigen::VectorXd::Zero(6);
  data.triangles = {Eigen::Vector3i(0, 1, 5), Eigen::Vector3i(2, 3, 4)};
  const auto model = ClothModel::Create(data);
  EXPECT_EQ(CountCrossingEdges(*model, model->rest_positions()), 0);
}

TEST(SelfCollision, ImpactZonesAloneStopTheFastParticleKeepingMomentum) {
  const double h = 1.0 / 240.0;
  const auto model = TwoTriangles(0.05, 1e-3, 1e-3);
  SelfCollisionSettings settings;
  settings.max_iterations = 0;  // no impulse passes: straight to the impact-zone fallback
  SelfCollision self_collision(model, settings);
  const Points start = model->rest_positions();
  ClothState state = EndOfStraightStep(*model, h, {0, 0, 0, -20, 0, 0});

  const SelfCollisionReport report = self_collision.Resolve(start, h, state);

  EXPECT_EQ(report.collision_impulses, 0);
  EXPECT_GE(report.zone_particles, 4);  // the falling particle and the triangle it hit
  EXPECT_EQ(report.remaining_collisions, 0);
  EXPECT_EQ(CountCrossingEdges(*model, state.positions), 0);
  EXPECT_NEAR(Momentum(*model, state.velocities).y(), -0.02, 1e-14);
}

TEST(SelfCollision, RepeatedResolveAllocatesNothing) {
  const double h = 1.0 / 240.0;
  const auto model = TwoTriangles(0.003, 1e-3, 2e-3);
  SelfCollision self_collision(model, SelfCollisionSettings{});
  const Points start = model->rest_positions();
  ClothState state = EndOfStraightStep(*model, h, {1, 1, 1, -1, -1, -1});
  const ClothState input = state;
  self_collision.Resolve(start, h, state);  // first call: buffers reach their size
  state.positions = input.positions;
  state.velocities = input.velocities;
  const std::size_t before = g_allocations;
  const SelfCollisionReport report = self_collision.Resolve(start, h, state);
  EXPECT_EQ(g_allocations, before);
  EXPECT_GT(report.proximity_impulses, 0);
  state.positions = input.positions;
  state.velocities = input.velocities;
  const SelfCollisionReport move = self_collision.ResolveMove(start, h, state);
  EXPECT_EQ(g_allocations, before);
  EXPECT_GT(move.proximity_impulses, 0);
}

TEST(SelfCollision, RefusesAHoldNamingNoParticleLeavingTheStateUntouched) {
  const double h = 1.0 / 240.0;
  const auto model = TwoTriangles(0.003, 1e-3, 1e-3);
  SelfCollision self_collision(model, SelfCollisionSettings{});
  const Points start = model->rest_positions();
  ClothState state = EndOfStraightStep(*model, h, {0, 0, 0, -1, -1, -1});
  const ClothState input = state;
  for (const BodyHold& bad : {BodyHold{6, Vec3::UnitY()}, BodyHold{-1, Vec3::UnitY()},
                              BodyHold{0, Vec3(NAN, 0, 0)}}) {
    const SelfCollisionReport report = self_collision.Resolve(start, h, state, {bad});
    EXPECT_TRUE(report.skipped) << "particle " << bad.particle;
    EXPECT_EQ(state.positions, input.positions);
    EXPECT_EQ(state.velocities, input.velocities);
  }
}

TEST(SelfCollision, RefusesBadSettingsNamingTheField) {
  const auto model = TwoTriangles(0.01, 1e-3, 1e-3);
  SelfCollisionSettings settings;
  settings.thickness = -1.0;
  try {
    SelfCollision self_collision(model, settings);
    FAIL() << "expected InputError";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("thickness"), std::string::npos) << e.what();
  }
  settings = SelfCollisionSettings{};
  settings.particle_friction = {0.3, 0.3};  // the model has six particles
  try {
    SelfCollision self_collision(model, settings);
    FAIL() << "expected InputError";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("particle_friction has 2 values"), std::string::npos)
        << e.what();
  }
  settings.particle_friction.assign(model->num_particles(), 0.3);
  settings.particle_friction[4] = std::nan("");
  try {
    SelfCollision self_collision(model, settings);
    FAIL() << "expected InputError";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("particle_friction[4]"), std::string::npos) << e.what();
  }
}

// ---- the test: a folded napkin dropped on a sphere -------------------------------

constexpr int kNapkinSize = 21;      // particles per side
constexpr double kNapkinWidth = 0.5;  // m
constexpr double kFoldGap = 0.02;     // m between the halves

/// A 21×21, 0.5 m lattice of stiff cotton folded like a napkin: rows 0–10 flat at y = 0.05,
/// rows 11–20 laid back over rows 10–1, 2 cm higher.
std::shared_ptr<const ClothModel> FoldedNapkin() {
  LatticePanel panel;
  panel.origin = Vec3(-0.25, 0.05, -0.25);
  panel.width = panel.height = kNapkinWidth;
  panel.cols = panel.rows = kNapkinSize;
  ClothModelData data = BuildLatticePanel(panel, Material{}, "napkin");
  const Points flat = data.rest_positions;
  for (int i = kNapkinSize / 2 + 1; i < kNapkinSize; ++i) {
    for (int j = 0; j < kNapkinSize; ++j) {
      data.rest_positions.row(i * kNapkinSize + j) =
          flat.row((kNapkinSize - i) * kNapkinSize + j) + Eigen::RowVector3d(0, kFoldGap, 0);
    }
  }
  return ClothModel::Create(std::move(data));
}

struct DropOutcome {
  int crossing_edges = 0;
  int steps_with_remaining_collisions = 0;
  double worst_self_collision_ms = 0.0;
  double mean_self_collision_ms = 0.0;
  bool rolled_back = false;
};

/// Drops the folded napkin onto a sphere under its folded part and simulates 1.5 s in steps
/// of 1/240 s the way sim_core/scene/simulation.cc does (sphere contacts in the solve, strain
/// limit, projection out of the sphere), then, when asked, self-collision on the step's path.
DropOutcome DropFoldedNapkin(bool with_self_collision) {
  const auto model = FoldedNapkin();
  const double h = 1.0 / 240.0;
  ImplicitStepper stepper(model, StepperSettings{});
  SphereObstacle sphere;
  sphere.radius = 0.12;
  sphere.center = Vec3(0.0, -sphere.radius - sphere.thickness, -0.12);
  std::unique_ptr<SelfCollision> self_collision;
  if (with_self_collision) {
    self_collision = std::make_unique<SelfCollision>(model, SelfCollisionSettings{});
  }
  ClothState state = ClothState::AtRest(*model);
  Points start = state.positions;
  std::vector<Contact> contacts;
  contacts.reserve(model->num_particles());
  DropOutcome outcome;
  double total_ms = 0.0;
  const int steps = static_cast<int>(std::lround(1.5 / h));
  StrainLimiter limiter(*model);
  const StrainLimitSettings limit;
  for (int step = 0; step < steps; ++step) {
    start = state.positions;
    limiter.BeginStep(state.positions);
    contacts.clear();
    FindSphereContacts(sphere, state.positions, state.velocities, h, 0.5 * sphere.thickness,
                       contacts);
    const StepReport report = stepper.Step(state, h, contacts);
    outcome.rolled_back = outcome.rolled_back || report.rolled_back;
    limiter.SetTargets(*model, limit, state.positions);
    limiter.AddPlanes(contacts);
    limiter.Limit(*model, limit, state);
    ProjectOutOfSphere(sphere, state.positions, state.velocities);
    if (self_collision) {
      const auto t0 = std::chrono::steady_clock::now();
      const SelfCollisionReport sc = self_collision->Resolve(start, h, state);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      total_ms += ms;
      outcome.worst_self_collision_ms = std::max(outcome.worst_self_collision_ms, ms);
      outcome.steps_with_remaining_collisions += sc.remaining_collisions > 0 ? 1 : 0;
    }
  }
  outcome.mean_self_collision_ms = total_ms / steps;
  outcome.crossing_edges = CountCrossingEdges(*model, state.positions);
  return outcome;
}

TEST(SelfCollision, FoldedNapkinDroppedOnASphereEndsWithoutCrossingEdges) {
  const auto model = FoldedNapkin();
  ASSERT_EQ(CountCrossingEdges(*model, model->rest_positions()), 0);  // starts clean

  const DropOutcome without = DropFoldedNapkin(false);
  const DropOutcome with = DropFoldedNapkin(true);

  EXPECT_FALSE(without.rolled_back);
  EXPECT_FALSE(with.rolled_back);
  EXPECT_GT(without.crossing_edges, 0) << "the scene must be able to fail";
  EXPECT_EQ(with.crossing_edges, 0);
  EXPECT_EQ(with.steps_with_remaining_collisions, 0);
  std::printf("folded napkin: %d crossing edges without self-collision, %d with; "
              "self-collision %.3f ms mean, %.3f ms worst per step\n",
              without.crossing_edges, with.crossing_edges, with.mean_self_collision_ms,
              with.worst_self_collision_ms);
}


/// Edges through triangles by brute force, every unique edge against every triangle sharing
/// no particle with it, with the segment-triangle test written here: the ends strictly on
/// opposite sides of the plane (beyond 1e-12 of the largest term) and the line strictly
/// inside the triangle.
int BruteForceCrossings(const ClothModel& model, const Points& x) {
  std::set<std::pair<int, int>> edges;
  for (const Eigen::Vector3i& t : model.triangles()) {
    for (int k = 0; k < 3; ++k) edges.insert(std::minmax(t[k], t[(k + 1) % 3]));
  }
  const auto orient = [](const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    return (b - a).cross(c - a).dot(d - a);
  };
  int count = 0;
  for (const auto& [a, b] : edges) {
    const Vec3 p = x.row(a), q = x.row(b);
    for (const Eigen::Vector3i& t : model.triangles()) {
      if ((t.array() == a).any() || (t.array() == b).any()) continue;
      const Vec3 u = x.row(t[0]), v = x.row(t[1]), w = x.row(t[2]);
      const double sp = orient(u, v, w, p), sq = orient(u, v, w, q);
      const double eps = 1e-12 * (v - u).norm() * (w - u).norm() *
                         std::max((p - u).norm(), (q - u).norm());
      if (!((sp > eps && sq < -eps) || (sp < -eps && sq > eps))) continue;
      const double o1 = orient(p, q, u, v), o2 = orient(p, q, v, w), o3 = orient(p, q, w, u);
      if ((o1 > 0 && o2 > 0 && o3 > 0) || (o1 < 0 && o2 < 0 && o3 < 0)) {
        ++count;
        break;
      }
    }
  }
  return count;
}

TEST(CountCrossingEdges, CountsWhatTheBruteForceCounts) {
  LatticePanel panel;
  panel.cols = panel.rows = 12;
  const auto model = ClothModel::Create(BuildLatticePanel(panel, Material{}, "crumpled"));
  std::srand(11);
  for (double height : {0.0, 0.02, 0.1, 0.5}) {  // flat to thoroughly crumpled
    Points x = model->rest_positions();
    for (Eigen::Index i = 0; i < x.rows(); ++i) {
      x(i, 1) += height * (std::rand() / double(RAND_MAX));
      x(i, 0) += 0.3 * height * (std::rand() / double(RAND_MAX) - 0.5);
    }
    EXPECT_EQ(CountCrossingEdges(*model, x), BruteForceCrossings(*model, x)) << height;
  }
}

}  // namespace
}  // namespace costume::sim
