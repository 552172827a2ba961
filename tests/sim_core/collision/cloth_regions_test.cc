// Cloth-side adaptive regions: the hierarchy covers every particle once, cones hold every
// triangle normal, and the mesh collider finds the same contacts with regions on, off and
// by closed form on a box, while a flat sheet needs far fewer broad-phase queries.
#include "sim_core/collision/cloth_regions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <random>

#include "sim_core/avatar/skeleton.h"
#include "sim_core/cloth/lattice_panel.h"
#include "sim_core/cloth/material.h"
#include "sim_core/collision/mesh_collider.h"
#include "sim_core/common/input_error.h"
#include "tests/sim_core/collision/test_meshes.h"

#include "tests/support/contact_rule.h"
#include "tests/support/count_mallocs.h"

namespace costume::sim {
namespace {

using test::TestMesh;

constexpr double kH = 1.0 / 60.0;
constexpr double kThickness = 0.004;
constexpr double kMargin = 0.003;
// The avatar: a box whose top face is the plane y = kTop.
const Eigen::Vector3d kCenter(0.0, 0.8, 0.0);
const Eigen::Vector3d kHalf(0.35, 0.2, 0.35);
const double kTop = kCenter.y() + kHalf.y();
const std::vector<Eigen::Isometry3d> kJoints = {Eigen::Isometry3d::Identity()};

using test::RigidAvatar;

// A size × size lattice sheet, 0.5 m square; `lattice` false drops the lattice shape so
// the regions are grown over the triangles instead.
std::shared_ptr<const ClothModel> Sheet(int size, bool lattice = true) {
  LatticePanel panel;
  panel.rows = panel.cols = size;
  panel.width = panel.height = 0.5;
  panel.origin = Eigen::Vector3d(-0.25, kTop + 0.002, -0.25);
  ClothModelData data = BuildLatticePanel(panel, NamedMaterial("stiff_cotton"), "sheet");
  if (!lattice) data.lattice_rows = data.lattice_cols = 0;
  return ClothModel::Create(std::move(data));
}

// The sheet's particles folded into a tight zig-zag along x (a fold at every column,
// alternating between 6 mm below and 14 mm above the top face, 2 mm apart in x), with a
// little crumpling noise: every base region is far from flat.
Points FoldedPositions(const ClothModel& sheet, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> noise(-0.002, 0.002);
  Points x = sheet.rest_positions();
  const int cols = sheet.lattice_cols();
  for (int p = 0; p < sheet.num_particles(); ++p) {
    const int j = p % cols;
    x(p, 0) = -0.06 + 0.002 * j + noise(rng);
    x(p, 1) = kTop + (j % 2 == 0 ? -0.006 : 0.014) + noise(rng);
    x(p, 2) += noise(rng);
  }
  return x;
}

Points RandomVelocities(int n, double scale, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> speed(-scale, scale);
  Points v(n, 3);
  for (int i = 0; i < n; ++i) v.row(i) = Eigen::Vector3d(speed(rng), speed(rng), speed(rng));
  return v;
}

// ---- the hierarchy ---------------------------------------------------------------------

// Every particle is in exactly one base region, every node's range is its children's
// ranges one after another, and base regions stay within the size asked for.
void ExpectCoversEveryParticleOnce(const ClothRegions& regions, int n, int max_region) {
  ASSERT_EQ(regions.num_particles(), n);
  std::vector<int> seen(n, 0);
  for (int p : regions.particles()) {
    ASSERT_GE(p, 0);
    ASSERT_LT(p, n);
    ++seen[p];
  }
  for (int p = 0; p < n; ++p) EXPECT_EQ(seen[p], 1) << p;
  std::vector<int> slot_owner(n, 0);
  int num_base = 0;
  for (int k = 0; k < regions.num_nodes(); ++k) {
    const ClothRegionNode& node = regions.nodes()[k];
    EXPECT_EQ(node.parent < 0, k < regions.num_roots()) << k;
    if (node.num_children == 0) {
      ++num_base;
      EXPECT_GE(node.count, 1);
      EXPECT_LE(node.count, max_region);
      for (int s = node.first; s < node.first + node.count; ++s) ++slot_owner[s];
      continue;
    }
    EXPECT_GE(node.num_children, 2);
    EXPECT_LE(node.num_children, 4);
    int next = node.first;
    for (int c = node.first_child; c < node.first_child + node.num_children; ++c) {
      EXPECT_GT(c, k);
      EXPECT_EQ(regions.nodes()[c].parent, k);
      EXPECT_EQ(regions.nodes()[c].first, next);
      next += regions.nodes()[c].count;
    }
    EXPECT_EQ(next, node.first + node.count);
  }
  EXPECT_EQ(num_base, regions.num_base_regions());
  for (int s = 0; s < n; ++s) EXPECT_EQ(slot_owner[s], 1) << s;
  int root_total = 0;
  for (int k = 0; k < regions.num_roots(); ++k) root_total += regions.nodes()[k].count;
  EXPECT_EQ(root_total, n);
}

// The selected nodes hold every particle exactly once.
void ExpectSelectionCoversOnce(const ClothRegions& regions, const std::vector<int>& selected) {
  std::vector<int> seen(regions.num_particles(), 0);
  for (int k : selected) {
    const ClothRegionNode& node = regions.nodes()[k];
    for (int s = node.first; s < node.first + node.count; ++s) ++seen[regions.particles()[s]];
  }
  for (int p = 0; p < regions.num_particles(); ++p) ASSERT_EQ(seen[p], 1) << p;
}

TEST(ClothRegions, LatticeHierarchyCoversEveryParticleOnce) {
  const auto sheet = Sheet(65);
  ClothRegions regions(*sheet, 8);
  // 65 / 8 rounds to 8 blocks a side: 64 base regions of 8 or 9 rows and columns.
  EXPECT_EQ(regions.num_base_regions(), 64);
  EXPECT_EQ(regions.num_roots(), 1);
  ExpectCoversEveryParticleOnce(regions, 65 * 65, 9 * 9);
  // A quadtree: 64 + 16 + 4 + 1 nodes.
  EXPECT_EQ(regions.num_nodes(), 85);
}

TEST(ClothRegions, GrownHierarchyCoversEveryParticleOnceAcrossPieces) {
  // Two sheets side by side and one loose particle: three pieces, three roots.
  const auto a = Sheet(20, false);
  ClothModelData data = a->data();
  const int n = a->num_particles();
  data.rest_positions.conservativeResize(2 * n + 1, 3);
  data.masses.conservativeResize(2 * n + 1);
  data.areas.conservativeResize(2 * n + 1);
  for (int p = 0; p < n; ++p) {
    data.rest_positions.row(n + p) = a->rest_positions().row(p) + Eigen::RowVector3d(1, 0, 0);
    data.masses[n + p] = a->masses()[p];
    data.areas[n + p] = a->areas()[p];
  }
  data.rest_positions.row(2 * n) = Eigen::RowVector3d(3, 3, 3);
  data.masses[2 * n] = 0.01;
  data.areas[2 * n] = 0.0;
  for (const Eigen::Vector3i& t : a->triangles()) data.triangles.push_back(t.array() + n);
  data.springs.clear();
  data.drag.resize(0);
  const auto cloth = ClothModel::Create(std::move(data));
  ClothRegions regions(*cloth, 6);
  EXPECT_EQ(regions.num_roots(), 3);
  ExpectCoversEveryParticleOnce(regions, 2 * n + 1, 36);
  EXPECT_GE(regions.num_base_regions(), 2 * (400 / 36) + 1);
}

// A leaf's cone is exactly the widest of its triangles' normals; every node's cone holds
// every triangle normal below it.
TEST(ClothRegions, ConesHoldEveryTriangleNormalBelowThem) {
  const auto sheet = Sheet(33);
  ClothRegions regions(*sheet, 8);
  const Points x = FoldedPositions(*sheet, 5);
  const std::vector<double> half(sheet->num_particles(), 0.01);
  regions.Refit(x, half.data());
  std::vector<int> leaf_of(sheet->num_particles());
  for (int k = 0; k < regions.num_nodes(); ++k) {
    const ClothRegionNode& node = regions.nodes()[k];
    if (node.num_children > 0) continue;
    for (int s = node.first; s < node.first + node.count; ++s) leaf_of[regions.particles()[s]] = k;
  }
  std::vector<double> widest(regions.num_nodes(), 0.0);
  for (const Eigen::Vector3i& t : sheet->triangles()) {
    const Eigen::Vector3d a = x.row(t[0]), b = x.row(t[1]), c = x.row(t[2]);
    const Eigen::Vector3d normal = (b - a).cross(c - a).normalized();
    for (int k = leaf_of[t[0]]; k >= 0; k = regions.nodes()[k].parent) {
      const double cos_angle = normal.dot(regions.nodes()[k].cone_axis);
      const double angle = std::acos(std::clamp(cos_angle, -1.0, 1.0));
      EXPECT_LE(angle, regions.nodes()[k].cone_angle + 1e-9) << k;
      widest[k] = std::max(widest[k], angle);
    }
  }
  for (int k = 0; k < regions.num_nodes(); ++k) {
    if (regions.nodes()[k].num_children == 0) {
      EXPECT_NEAR(regions.nodes()[k].cone_angle, widest[k], 1e-9);
    }
  }
  // Folds at every column: normals swing by about ±80°, so nothing is flat at 0.35 rad.
  const auto& selected = regions.Select(0.35);
  EXPECT_EQ(static_cast<int>(selected.size()), regions.num_base_regions());
  ExpectSelectionCoversOnce(regions, selected);
}

TEST(ClothRegions, FlatSheetIsTakenWholeAndBoxesHoldEveryParticleBox) {
  const auto sheet = Sheet(33);
  ClothRegions regions(*sheet, 8);
  std::vector<double> half(sheet->num_particles());
  for (int p = 0; p < sheet->num_particles(); ++p) half[p] = 0.001 * (p % 7);
  half[5] = -1.0;  // left out
  regions.Refit(sheet->rest_positions(), half.data());
  const auto& selected = regions.Select(0.01);
  ASSERT_EQ(selected.size(), 1u);
  EXPECT_EQ(selected[0], 0);
  EXPECT_NEAR(regions.nodes()[0].cone_angle, 0.0, 1e-9);
  // The root's box is the particles' boxes' box, found independently.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (int p = 0; p < sheet->num_particles(); ++p) {
    if (p == 5) continue;
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], sheet->rest_positions()(p, a) - half[p]);
      hi[a] = std::max(hi[a], sheet->rest_positions()(p, a) + half[p]);
    }
  }
  EXPECT_EQ(regions.nodes()[0].box_min, lo);
  EXPECT_EQ(regions.nodes()[0].box_max, hi);
}

TEST(ClothRegions, RefusesBadRegionSize) {
  EXPECT_THROW(ClothRegions(*Sheet(5), 0), InputError);
  EXPECT_THROW(ClothRegions(*Sheet(5), 257), InputError);
}

// ---- the collider with cloth regions ---------------------------------------------------

struct ExpectedContact {
  int particle;
  double target;
};

// The box's closed form: particles here are over the top face's interior (|x|, |z| well
// inside), within 1 cm below it or above it, so the signed distance is y − top and the
// normal +y; the box is at rest.
std::vector<ExpectedContact> ClosedFormContacts(const Points& x, const Points& v) {
  std::vector<ExpectedContact> contacts;
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    const Eigen::Vector3d p = x.row(i).transpose();
    const double d = test::BoxSignedDistance(p, kCenter, kHalf);
    EXPECT_NEAR(d, p.y() - kTop, 1e-12);  // the premise
    if (d >= kThickness && d + kH * v(i, 1) > kThickness + kMargin) continue;
    contacts.push_back(
        {static_cast<int>(i), costume::test::ExpectedContactVelocity(0.0, d - kThickness, v(i, 1), kH)});
  }
  return contacts;
}

struct Colliders {
  // Adaptive cloth regions, none, none because SetCloth was not called, fixed (base)
  // cloth regions.
  std::unique_ptr<MeshCollider> on, off, unset, fixed;
};

Colliders MakeColliders(const ClothModel& sheet) {
  const TestMesh box = test::TessellatedBox(kCenter, kHalf, Eigen::Vector3i(28, 8, 28));
  const auto avatar = RigidAvatar(box);
  BodyCollisionSettings settings;
  settings.thickness = kThickness;
  MeshCollisionOptions on_options;
  on_options.max_penetration = 0.02;
  on_options.cloth_regions = true;
  MeshCollisionOptions off_options = on_options;
  off_options.cloth_regions = false;
  Colliders c;
  c.on = std::make_unique<MeshCollider>(avatar, settings, on_options);
  c.off = std::make_unique<MeshCollider>(avatar, settings, off_options);
  c.unset = std::make_unique<MeshCollider>(avatar, settings, on_options);
  MeshCollisionOptions fixed_options = on_options;
  fixed_options.cloth_adaptive = false;
  c.fixed = std::make_unique<MeshCollider>(avatar, settings, fixed_options);
  c.on->SetCloth(sheet);
  c.off->SetCloth(sheet);
  c.fixed->SetCloth(sheet);
  for (MeshCollider* collider : {c.on.get(), c.off.get(), c.unset.get(), c.fixed.get()}) {
    collider->Update(kJoints, box.vertices, kH);
  }
  return c;
}

void ExpectSameContacts(const std::vector<Contact>& got, const std::vector<Contact>& reference,
                        const std::vector<ExpectedContact>& closed_form) {
  ASSERT_EQ(got.size(), reference.size());
  ASSERT_EQ(got.size(), closed_form.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    ASSERT_EQ(got[k].particle, reference[k].particle);
    // The same searches in the same order: bit for bit the same.
    EXPECT_EQ(got[k].normal, reference[k].normal);
    EXPECT_EQ(got[k].target_normal_velocity, reference[k].target_normal_velocity);
    ASSERT_EQ(got[k].particle, closed_form[k].particle);
    EXPECT_LT((got[k].normal - Eigen::Vector3d::UnitY()).norm(), 1e-12);
    EXPECT_NEAR(got[k].target_normal_velocity, closed_form[k].target, 1e-7);
  }
}

TEST(MeshColliderClothRegions, FlatSheetSameContactsWithFarFewerQueries) {
  const auto sheet = Sheet(33);
  Colliders c = MakeColliders(*sheet);
  const Points x = sheet->rest_positions();  // 2 mm above the top face
  const Points v = RandomVelocities(sheet->num_particles(), 0.3, 3);
  std::vector<Contact> on, off, unset, fixed;
  c.on->FindContacts(x, v, kH, kMargin, on);
  c.off->FindContacts(x, v, kH, kMargin, off);
  c.unset->FindContacts(x, v, kH, kMargin, unset);
  c.fixed->FindContacts(x, v, kH, kMargin, fixed);
  const auto expected = ClosedFormContacts(x, v);
  ASSERT_EQ(expected.size(), x.rows());  // all within the thickness
  ExpectSameContacts(on, off, expected);
  ExpectSameContacts(unset, off, expected);
  ExpectSameContacts(fixed, off, expected);
  EXPECT_EQ(c.fixed->num_broad_phase_queries(), c.fixed->cloth_regions()->num_base_regions());
  EXPECT_EQ(c.off->num_broad_phase_queries(), sheet->num_particles());
  EXPECT_EQ(c.unset->num_broad_phase_queries(), sheet->num_particles());
  EXPECT_EQ(c.on->num_broad_phase_queries(), 1);  // the whole sheet is flat
  EXPECT_EQ(c.off->stats().num_tests, c.unset->stats().num_tests);
  EXPECT_LT(c.on->stats().num_tests, c.off->stats().num_tests);
  EXPECT_EQ(c.on->stats().num_contacts, static_cast<int>(on.size()));
  std::printf("flat: queries %lld on / %lld off; tests %lld on / %lld fixed / %lld off\n",
              c.on->num_broad_phase_queries(), c.off->num_broad_phase_queries(),
              c.on->stats().num_tests, c.fixed->stats().num_tests, c.off->stats().num_tests);
}

TEST(MeshColliderClothRegions, FoldedSheetSameContactsQueryingEveryBaseRegion) {
  const auto sheet = Sheet(33);
  Colliders c = MakeColliders(*sheet);
  const Points x = FoldedPositions(*sheet, 11);
  const Points v = RandomVelocities(sheet->num_particles(), 0.5, 13);
  std::vector<Contact> on, off, fixed;
  c.on->FindContacts(x, v, kH, kMargin, on);
  c.off->FindContacts(x, v, kH, kMargin, off);
  c.fixed->FindContacts(x, v, kH, kMargin, fixed);
  const auto expected = ClosedFormContacts(x, v);
  ASSERT_GT(expected.size(), 200u);
  ASSERT_LT(expected.size(), static_cast<std::size_t>(x.rows()) - 200);  // both cases
  ExpectSameContacts(on, off, expected);
  ExpectSameContacts(fixed, off, expected);
  EXPECT_EQ(c.on->num_broad_phase_queries(), c.on->cloth_regions()->num_base_regions());
  std::printf("folded: queries %lld on / %lld off; tests %lld on / %lld fixed / %lld off\n",
              c.on->num_broad_phase_queries(), c.off->num_broad_phase_queries(),
              c.on->stats().num_tests, c.fixed->stats().num_tests, c.off->stats().num_tests);
}

TEST(MeshColliderClothRegions, StaleConesChangeOnlyHowCoarselyTheClothQueries) {
  // By default a quarter of the base regions refresh their cone per call: right after the
  // sheet folds, most cones still say flat and folded nodes are taken whole, yet the
  // contacts are those of per-particle queries; four calls later every cone is current.
  const auto sheet = Sheet(33);
  Colliders c = MakeColliders(*sheet);
  const Points flat = sheet->rest_positions();
  const Points folded = FoldedPositions(*sheet, 11);
  const Points v = RandomVelocities(sheet->num_particles(), 0.5, 13);
  std::vector<Contact> on, off;
  c.on->FindContacts(flat, v, kH, kMargin, on);
  EXPECT_EQ(c.on->num_broad_phase_queries(), 1);
  const int base_regions = c.on->cloth_regions()->num_base_regions();
  for (int call = 0; call < 4; ++call) {
    on.clear();
    off.clear();
    c.on->FindContacts(folded, v, kH, kMargin, on);
    c.off->FindContacts(folded, v, kH, kMargin, off);
    ASSERT_EQ(on.size(), off.size());
    for (std::size_t k = 0; k < on.size(); ++k) {
      ASSERT_EQ(on[k].particle, off[k].particle);
      EXPECT_EQ(on[k].normal, off[k].normal);
      EXPECT_EQ(on[k].target_normal_velocity, off[k].target_normal_velocity);
    }
  }
  EXPECT_EQ(c.on->num_broad_phase_queries(), base_regions);
}

TEST(ClothRegions, ConePeriodRefreshesTheBaseRegionsInTurns) {
  const auto sheet = Sheet(33);
  ClothRegions regions(*sheet, 8);
  const std::vector<double> half(sheet->num_particles(), 0.01);
  auto folded_leaves = [&] {
    int n = 0;
    for (const ClothRegionNode& node : regions.nodes()) {
      if (node.num_children == 0 && node.cone_angle > 0.5) ++n;
    }
    return n;
  };
  regions.Refit(sheet->rest_positions(), half.data(), true, 4);  // first call: every cone
  EXPECT_EQ(folded_leaves(), 0);
  const Points folded = FoldedPositions(*sheet, 11);
  const int base = regions.num_base_regions();
  for (int call = 1; call <= 4; ++call) {
    regions.Refit(folded, half.data(), true, 4);
    EXPECT_EQ(folded_leaves(), call * base / 4) << call;  // 16 base regions, 4 per call
  }
}

TEST(MeshColliderClothRegions, OtherParticleCountsAndBadParticlesFallBackSafely) {
  const auto sheet = Sheet(17);
  Colliders c = MakeColliders(*sheet);
  Points x = sheet->rest_positions();
  Points v = RandomVelocities(sheet->num_particles(), 0.3, 7);
  x(4, 0) = std::numeric_limits<double>::quiet_NaN();
  v(9, 2) = std::numeric_limits<double>::infinity();
  std::vector<Contact> on, off;
  c.on->FindContacts(x, v, kH, kMargin, on);
  c.off->FindContacts(x, v, kH, kMargin, off);
  ASSERT_EQ(on.size(), off.size());
  ASSERT_EQ(on.size(), static_cast<std::size_t>(x.rows()) - 2);
  for (std::size_t k = 0; k < on.size(); ++k) EXPECT_EQ(on[k].particle, off[k].particle);
  // A different particle count: per-particle queries.
  const Points part = x.topRows(10), part_v = v.topRows(10) * 0.0;
  on.clear();
  c.on->FindContacts(part, part_v, kH, kMargin, on);
  EXPECT_EQ(c.on->num_broad_phase_queries(), 8);  // particles 4 and 9 are skipped
  EXPECT_EQ(on.size(), 8u);
}

TEST(MeshColliderClothRegions, FindContactsDoesNotAllocateAfterTheFirstCall) {
  const auto sheet = Sheet(33);
  Colliders c = MakeColliders(*sheet);
  const Points x = FoldedPositions(*sheet, 2);
  const Points v = RandomVelocities(sheet->num_particles(), 0.3, 4);
  std::vector<Contact> contacts;
  contacts.reserve(x.rows());
  c.on->FindContacts(x, v, kH, kMargin, contacts);
  ASSERT_GT(contacts.size(), 10u);
  contacts.clear();
  g_num_allocations = 0;
  g_count_allocations = true;
  c.on->FindContacts(x, v, kH, kMargin, contacts);
  contacts.clear();
  c.on->FindContacts(sheet->rest_positions(), v, kH, kMargin, contacts);
  g_count_allocations = false;
  EXPECT_EQ(contacts.size(), x.rows());  // the flat sheet, all in contact
  EXPECT_EQ(g_num_allocations, 0);
  std::vector<int> probe;  // the counter works
  g_count_allocations = true;
  probe.push_back(1);
  g_count_allocations = false;
  EXPECT_EQ(g_num_allocations, 1);
}

TEST(MeshColliderClothRegions, RefusesBadClothOptions) {
  const auto avatar =
      RigidAvatar(test::TessellatedBox(kCenter, kHalf, Eigen::Vector3i(2, 2, 2)));
  MeshCollisionOptions options;
  options.cloth_region_size = 0;
  EXPECT_THROW(MeshCollider(avatar, BodyCollisionSettings{}, options), InputError);
  options = {};
  options.cloth_flatness_angle = -0.1;
  EXPECT_THROW(MeshCollider(avatar, BodyCollisionSettings{}, options), InputError);
}

}  // namespace
}  // namespace costume::sim
