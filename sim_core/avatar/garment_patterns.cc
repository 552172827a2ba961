#include "sim_core/avatar/garment_patterns.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <unordered_map>

#include "sim_core/cloth/lattice_panel.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

constexpr double kPi = std::numbers::pi;
/// No human body is thinner than this at the trunk [m]: a ring's half axis is never taken
/// below it (a section of one vertex has none).
constexpr double kThinnestBody = 0.01;
/// Heights a humanoid's rest pose may stand between [m], hips above the knees above the
/// floor: outside, the avatar's unit or its up axis was misread.
constexpr double kShortestBody = 0.3, kTallestBody = 3.0;

/// Throws InputError naming the avatar unless it stands as a humanoid does in a rest pose:
/// knees below hips below the waist below the shoulders, the line from the knees to the
/// shoulders within 45° of vertical, and a body of human size.
void RequireUpright(const Avatar& avatar) {
  using J = HAnimJoint;
  const Skeleton& s = avatar.skeleton();
  const auto mid = [&](J a, J b) {
    return 0.5 * (s.rest_world()[s.Find(a)].translation() + s.rest_world()[s.Find(b)].translation());
  };
  const Eigen::Vector3d knees = mid(J::kLKnee, J::kRKnee), hips = mid(J::kLHip, J::kRHip),
                        shoulders = mid(J::kLShoulder, J::kRShoulder);
  const double waist = s.rest_world()[s.Find(J::kVl5)].translation().y();
  const std::string who = "avatar '" + avatar.name() + "': ";
  const double rise = shoulders.y() - knees.y();
  if (!(knees.y() < hips.y() && hips.y() < waist + 0.05 && waist < shoulders.y() &&
        rise >= std::cos(kPi / 4) * (shoulders - knees).norm())) {
    const auto at = [](const char* joint, double y) {
      return std::string(joint) + " at " + FormatValue(y) + " m";
    };
    throw InputError(who + "its rest pose is not upright, so no garment can be placed: " +
                     at("knees", knees.y()) + ", " + at("hips", hips.y()) + ", " +
                     at("vl5", waist) + ", " + at("shoulders", shoulders.y()) +
                     " high (expected rising in that order, knees to shoulders within 45° of "
                     "vertical, y up: declare the file's up axis)");
  }
  const Eigen::VectorXd heights = avatar.rest_vertices().col(1);
  const double height = heights.maxCoeff() - heights.minCoeff();
  if (!(height >= kShortestBody && height <= kTallestBody)) {
    throw InputError(who + "stands " + FormatValue(height) + " m tall (allowed " +
                     FormatValue(kShortestBody) + " to " + FormatValue(kTallestBody) +
                     " m for a garment: declare the file's unit)");
  }
}

/// The cross-section of the skin at height y of the vertices belonging to `segments`, from
/// a slab ±`slab` [m] thick; nullopt when the slab holds none.
std::optional<BodySection> Section(const Avatar& avatar, double y,
                                   std::initializer_list<HAnimJoint> segments, double slab) {
  Eigen::Vector2d low = Eigen::Vector2d::Constant(1e9), high = -low;
  const auto& of = avatar.vertex_segments();
  for (int v = 0; v < avatar.num_vertices(); ++v) {
    const Eigen::Vector3d p = avatar.rest_vertices().row(v).transpose();
    if (std::abs(p.y() - y) > slab || !of[v]) continue;
    if (std::find(segments.begin(), segments.end(), *of[v]) == segments.end()) continue;
    low = low.cwiseMin(Eigen::Vector2d(p.x(), p.z()));
    high = high.cwiseMax(Eigen::Vector2d(p.x(), p.z()));
  }
  if (low.x() > high.x()) return std::nullopt;
  BodySection section;
  section.height = y;
  section.centre_x = 0.5 * (low.x() + high.x());
  section.centre_z = 0.5 * (low.y() + high.y());
  section.half_width = 0.5 * (high.x() - low.x());
  section.half_depth = 0.5 * (high.y() - low.y());
  return section;
}

BodySection RequireSection(const Avatar& avatar, double y, std::initializer_list<HAnimJoint> segments,
                           const char* what) {
  for (double slab : {0.015, 0.05}) {
    if (auto section = Section(avatar, y, segments, slab)) return *section;
  }
  throw InputError("avatar '" + avatar.name() + "': no skin at the " + what + " (height " +
                   FormatValue(y) + " m) to fit a garment to");
}

double JointHeight(const Avatar& avatar, HAnimJoint a, HAnimJoint b) {
  const Skeleton& s = avatar.skeleton();
  return 0.5 * (s.rest_world()[s.Find(a)].translation().y() +
                s.rest_world()[s.Find(b)].translation().y());
}

/// An elliptic ring around the body at one height: the garment's shape there.
struct Ring {
  double height, half_width, half_depth;
};

Ring Around(const BodySection& s, double gap, double flare = 0.0) {
  return {s.height, s.half_width + gap + flare, s.half_depth + gap + flare};
}

/// The ring at height y, interpolated linearly between `rings` (ordered top to bottom).
Ring RingAt(const std::vector<Ring>& rings, double y) {
  if (y >= rings.front().height) return rings.front();
  for (std::size_t k = 1; k < rings.size(); ++k) {
    if (y >= rings[k].height) {
      const double t = (rings[k - 1].height - y) / (rings[k - 1].height - rings[k].height);
      return {y, (1 - t) * rings[k - 1].half_width + t * rings[k].half_width,
              (1 - t) * rings[k - 1].half_depth + t * rings[k].half_depth};
    }
  }
  return rings.back();
}

/// The ring widened (keeping its aspect) until it encloses the body slice nearest to its
/// height, `gap` included, around the centre (cx, cz).
Ring Enclosing(Ring ring, const BodyMeasures& m, double cx, double cz, double gap) {
  const BodySlice* nearest = nullptr;
  for (const BodySlice& slice : m.slices) {
    if (!nearest || std::abs(slice.height - ring.height) < std::abs(nearest->height - ring.height)) {
      nearest = &slice;
    }
  }
  if (!nearest) return ring;
  // First each half axis out to the slice's own extent along it, then both together: widened
  // at its aspect alone, a ring measured too flat (a section of few vertices) came out many
  // times too wide to enclose a round slice.
  double a = ring.half_width - gap, b = ring.half_depth - gap;
  for (const Eigen::Vector2d& p : nearest->points) {
    a = std::max(a, std::abs(p.x() - cx));
    b = std::max(b, std::abs(p.y() - cz));
  }
  a = std::max(a, kThinnestBody);
  b = std::max(b, kThinnestBody);
  double scale = 1.0;
  for (const Eigen::Vector2d& p : nearest->points) {
    scale = std::max(scale, std::hypot((p.x() - cx) / a, (p.y() - cz) / b));
  }
  return {ring.height, scale * a + gap, scale * b + gap};
}

/// A panel covering angles [theta0, theta1] (0 = front, increasing towards +x) of the
/// surface through `rings`, rows from the top ring to the bottom one.
struct PanelSpec {
  double theta0, theta1;
  int cols, rows;
};

/// Model data of one placed panel: the 12-neighbour lattice of BuildLatticePanel moved onto
/// the surface, with rest lengths, bending constants (k = B/(ℓ/2)²) and lumped masses taken
/// from the placed shape.
ClothModelData PlacePanel(const PanelSpec& spec, const std::vector<Ring>& rings,
                          const BodyMeasures& m, double cx, double cz, double gap,
                          const Material& material, const std::string& name) {
  LatticePanel flat;
  flat.cols = spec.cols;
  flat.rows = spec.rows;
  ClothModelData data = BuildLatticePanel(flat, material, name);
  const double top = rings.front().height, bottom = rings.back().height;
  for (int i = 0; i < spec.rows; ++i) {
    const double y = top - (top - bottom) * i / (spec.rows - 1);
    const Ring ring = Enclosing(RingAt(rings, y), m, cx, cz, gap);
    for (int j = 0; j < spec.cols; ++j) {
      const double theta = spec.theta0 + (spec.theta1 - spec.theta0) * j / (spec.cols - 1);
      data.rest_positions.row(i * spec.cols + j) << cx + ring.half_width * std::sin(theta), y,
          cz + ring.half_depth * std::cos(theta);
    }
  }
  for (Spring& s : data.springs) {
    s.rest_length = (data.rest_positions.row(s.b) - data.rest_positions.row(s.a)).norm();
    if (s.kind == SpringKind::kBending && material.bending_spring_k <= 0.0) {
      const double half = 0.5 * s.rest_length;
      s.stiffness = material.bending_rigidity / (half * half);
      s.damping = material.damping * s.stiffness;
    }
  }
  data.areas.setZero();
  for (const Eigen::Vector3i& t : data.triangles) {
    const Eigen::Vector3d a = data.rest_positions.row(t[0]), b = data.rest_positions.row(t[1]),
                          c = data.rest_positions.row(t[2]);
    const double third = (b - a).cross(c - a).norm() / 6.0;
    for (int k = 0; k < 3; ++k) data.areas[t[k]] += third;
  }
  data.masses = material.density * data.areas;
  data.drag = material.air_drag * data.areas;
  return data;
}

/// Particles of different panels closer than this are at the same place [m]: a seam's two
/// sides are computed from different angles (π/2 as the end of one panel and the start of
/// the next) and differ by rounding only.
constexpr double kSamePlace = 1e-9;

/// The sewn particles by place, in cells much larger than kSamePlace, so that finding the
/// one already at a place looks at 27 cells instead of every particle (a skirt at the
/// largest resolution, 1024, has some 250,000: comparing each with all took two minutes).
class Places {
 public:
  /// The lowest index among `positions` within kSamePlace of `x`, or -1.
  int Find(const Eigen::Vector3d& x, const std::vector<Eigen::Vector3d>& positions) const {
    const Cell c = CellOf(x);
    int found = -1;
    for (std::int64_t i = -1; i <= 1; ++i) {
      for (std::int64_t j = -1; j <= 1; ++j) {
        for (std::int64_t k = -1; k <= 1; ++k) {
          const auto it = cells_.find({c[0] + i, c[1] + j, c[2] + k});
          if (it == cells_.end()) continue;
          for (int q : it->second) {
            if ((positions[q] - x).norm() < kSamePlace && (found < 0 || q < found)) found = q;
          }
        }
      }
    }
    return found;
  }
  void Add(const Eigen::Vector3d& x, int index) { cells_[CellOf(x)].push_back(index); }

 private:
  using Cell = std::array<std::int64_t, 3>;
  struct CellHash {
    std::size_t operator()(const Cell& c) const {  // unsigned: wrapping is defined
      return static_cast<std::size_t>(static_cast<std::uint64_t>(c[0]) * 73856093u ^
                                      static_cast<std::uint64_t>(c[1]) * 19349663u ^
                                      static_cast<std::uint64_t>(c[2]) * 83492791u);
    }
  };
  static constexpr double kCell = 1e-6;  // [m]
  static Cell CellOf(const Eigen::Vector3d& x) {
    return {static_cast<std::int64_t>(std::floor(x.x() / kCell)),
            static_cast<std::int64_t>(std::floor(x.y() / kCell)),
            static_cast<std::int64_t>(std::floor(x.z() / kCell))};
  }
  std::unordered_map<Cell, std::vector<int>, CellHash> cells_;
};

/// Sews panels: particles of different panels at the same place become one; a spring both
/// panels had along the seam becomes one with their stiffnesses summed (each stood for half
/// a cell).
ClothModelData Sew(const std::vector<ClothModelData>& panels, const std::string& name) {
  ClothModelData whole;
  whole.name = name;
  std::vector<Eigen::Vector3d> positions;
  Places places;
  std::vector<double> masses, areas, drag;
  std::map<std::pair<int, int>, Spring> springs;
  for (const ClothModelData& panel : panels) {
    std::vector<int> index(panel.masses.size());
    for (Eigen::Index p = 0; p < panel.masses.size(); ++p) {
      const Eigen::Vector3d x = panel.rest_positions.row(p).transpose();
      int found = places.Find(x, positions);
      if (found < 0) {
        found = static_cast<int>(positions.size());
        positions.push_back(x);
        places.Add(x, found);
        masses.push_back(0.0), areas.push_back(0.0), drag.push_back(0.0);
      }
      masses[found] += panel.masses[p];
      areas[found] += panel.areas[p];
      drag[found] += panel.drag[p];
      index[p] = found;
    }
    for (Spring s : panel.springs) {
      s.a = index[s.a];
      s.b = index[s.b];
      if (s.a > s.b) std::swap(s.a, s.b);
      auto [it, inserted] = springs.try_emplace({s.a, s.b}, s);
      if (!inserted) {
        it->second.stiffness += s.stiffness;
        it->second.damping += s.damping;
      }
    }
    for (const Eigen::Vector3i& t : panel.triangles) {
      whole.triangles.emplace_back(index[t[0]], index[t[1]], index[t[2]]);
    }
  }
  const int n = static_cast<int>(positions.size());
  whole.rest_positions.resize(n, 3);
  for (int p = 0; p < n; ++p) whole.rest_positions.row(p) = positions[p].transpose();
  whole.masses = Eigen::Map<Eigen::VectorXd>(masses.data(), n);
  whole.areas = Eigen::Map<Eigen::VectorXd>(areas.data(), n);
  whole.drag = Eigen::Map<Eigen::VectorXd>(drag.data(), n);
  for (const auto& [pair, spring] : springs) whole.springs.push_back(spring);
  return whole;
}

/// Rows so that the vertical spacing is about the circumferential one.
int RowsFor(const std::vector<Ring>& rings, int resolution) {
  const Ring& widest = rings.back();
  const double circumference = kPi * (widest.half_width + widest.half_depth);
  const double spacing = circumference / resolution;
  return std::max(3, static_cast<int>(std::lround((rings.front().height - rings.back().height) / spacing)) + 1);
}

GarmentPattern Tube(const std::vector<Ring>& rings, const BodyMeasures& m, double gap,
                    const Material& material, int resolution, const std::string& name,
                    HAnimJoint attached_to) {
  const int cols = resolution / 2 + 1, rows = RowsFor(rings, resolution);
  const double cx = m.hips.centre_x, cz = m.hips.centre_z;
  const ClothModelData front = PlacePanel({-kPi / 2, kPi / 2, cols, rows}, rings, m, cx, cz,
                                          gap, material, name + " front");
  const ClothModelData back = PlacePanel({kPi / 2, 3 * kPi / 2, cols, rows}, rings, m, cx, cz,
                                         gap, material, name + " back");
  GarmentPattern pattern;
  pattern.data = Sew({front, back}, name);
  pattern.attached_to = attached_to;
  const double top = rings.front().height;
  for (int p = 0; p < pattern.data.rest_positions.rows(); ++p) {
    if (std::abs(pattern.data.rest_positions(p, 1) - top) < 1e-9) pattern.attached.push_back(p);
  }
  return pattern;
}

GarmentPattern Cape(const BodyMeasures& m, const Material& material, int resolution, double gap) {
  const BodySection collar{m.shoulders.height + 0.03, m.shoulders.centre_x, m.shoulders.centre_z,
                           m.shoulders.half_width, m.shoulders.half_depth};
  const std::vector<Ring> rings = {Around(collar, gap), Around(m.chest, gap),
                                   Around(m.hips, gap, 0.08),
                                   {m.knee_height, m.hips.half_width + gap + 0.15,
                                    m.hips.half_depth + gap + 0.2}};
  const int cols = resolution / 2 + 1, rows = RowsFor(rings, resolution);
  GarmentPattern pattern;
  pattern.data = PlacePanel({kPi - 0.9, kPi + 0.9, cols, rows}, rings, m, m.chest.centre_x,
                            m.chest.centre_z, gap, material, "cape");
  pattern.attached_to = HAnimJoint::kVc7;
  for (int j = 0; j < cols; ++j) pattern.attached.push_back(j);
  return pattern;
}

}  // namespace

BodyMeasures MeasureBody(const Avatar& avatar) {
  const Skeleton& s = avatar.skeleton();
  using J = HAnimJoint;
  for (J j : {J::kVl5, J::kVc7, J::kLHip, J::kRHip, J::kLKnee, J::kRKnee, J::kLShoulder, J::kRShoulder}) {
    if (s.Find(j) < 0) {
      throw InputError("avatar '" + avatar.name() + "': has no joint mapped onto H-Anim '" +
                       std::string(HAnimName(j)) + "', which garments are placed by");
    }
  }
  BodyMeasures m;
  const double shoulder_y = JointHeight(avatar, J::kLShoulder, J::kRShoulder);
  const double waist_y = s.rest_world()[s.Find(J::kVl5)].translation().y();
  RequireUpright(avatar);
  m.shoulders = RequireSection(avatar, shoulder_y, {J::kVl5, J::kVc7}, "shoulders");
  m.chest = RequireSection(avatar, shoulder_y - (shoulder_y - waist_y) / 3.0, {J::kVl5}, "chest");
  m.waist = RequireSection(avatar, waist_y, {J::kVl5, J::kSacroiliac, J::kHumanoidRoot}, "waist");
  m.hips = RequireSection(avatar, JointHeight(avatar, J::kLHip, J::kRHip),
                          {J::kSacroiliac, J::kHumanoidRoot, J::kLHip, J::kRHip, J::kVl5}, "hips");
  m.knee_height = JointHeight(avatar, J::kLKnee, J::kRKnee);
  const std::initializer_list<HAnimJoint> trunk_and_legs = {
      J::kHumanoidRoot, J::kSacroiliac, J::kVl5, J::kLHip, J::kRHip, J::kLKnee, J::kRKnee};
  constexpr double kSpacing = 0.02;
  for (double y = m.shoulders.height + 0.06; y > m.knee_height - 0.25; y -= kSpacing) {
    BodySlice slice;
    slice.height = y;
    const auto& of = avatar.vertex_segments();
    for (int v = 0; v < avatar.num_vertices(); ++v) {
      const Eigen::Vector3d p = avatar.rest_vertices().row(v).transpose();
      if (std::abs(p.y() - y) > kSpacing || !of[v]) continue;
      if (std::find(trunk_and_legs.begin(), trunk_and_legs.end(), *of[v]) != trunk_and_legs.end()) {
        slice.points.emplace_back(p.x(), p.z());
      }
    }
    m.slices.push_back(std::move(slice));
  }
  return m;
}

const std::vector<std::string>& BuiltInGarmentNames() {
  static const std::vector<std::string> names = {"skirt", "cape", "dress"};
  return names;
}

GarmentPattern MakeBuiltInGarment(const std::string& name, const BodyMeasures& m,
                                  const Material& material, int resolution, double gap) {
  RequireInRange("garment '" + name + "' resolution", resolution, 8, 1024, "");
  RequireInRange("garment '" + name + "' gap", gap, 0.0, 0.2, "m");
  if (name == "skirt") {
    // Ease at the hips (4 cm) and a flared hem leave the legs room to swing.
    const std::vector<Ring> rings = {Around(m.waist, gap), Around(m.hips, gap, 0.04),
                                     {m.knee_height - 0.05, m.hips.half_width + gap + 0.16,
                                      m.hips.half_depth + gap + 0.16}};
    return Tube(rings, m, gap, material, resolution, "skirt", HAnimJoint::kSacroiliac);
  }
  if (name == "dress") {
    // Strapless, its top halfway between the waist and the chest: higher, the hanging upper
    // arms would be inside it.
    const Ring chest = Around(m.chest, gap), waist = Around(m.waist, gap);
    const Ring top{0.5 * (chest.height + waist.height), 0.5 * (chest.half_width + waist.half_width),
                   0.5 * (chest.half_depth + waist.half_depth)};
    const std::vector<Ring> rings = {top, waist, Around(m.hips, gap, 0.03),
                                     {m.knee_height - 0.12, m.hips.half_width + gap + 0.1,
                                      m.hips.half_depth + gap + 0.1}};
    return Tube(rings, m, gap, material, resolution, "dress", HAnimJoint::kVl5);
  }
  if (name == "cape") return Cape(m, material, resolution, gap);
  std::string valid;
  for (const std::string& known : BuiltInGarmentNames()) valid += (valid.empty() ? "" : ", ") + known;
  throw InputError("garment '" + name + "' is not a built-in garment (built-in: " + valid + ")");
}

}  // namespace costume::sim
