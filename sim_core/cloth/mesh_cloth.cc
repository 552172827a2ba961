// Springs, masses and triangles of a cloth made from a general triangle/quad mesh.
//
// Spring rule (DESIGN.md "The cloth model": on a mesh, structural springs are edges, shear
// and bending springs join the far vertices of adjacent triangles and the two-ring):
// - structural: every side of every face (a quad's 4 sides; never the diagonal along which
//   a quad is split for bookkeeping);
// - shear: both diagonals of every quad; and across every edge shared by two triangles, of
//   which at least one is a triangle face (the other may be the half of a quad holding that
//   edge), the spring joining the two far (opposite) vertices. Quad–quad edges get none:
//   on a quad grid that would add knight's-move springs the lattice does not have. An edge
//   shared by more than two triangles (non-manifold) gets one spring per pair;
// - bending: for every vertex v and structural neighbour u, the structural neighbour w of u
//   (w != v, w not a structural neighbour of v) that continues the line v→u most nearly,
//   i.e. maximises cos∠(u − v, w − u), kept when that cosine is > 0.5 (60°). On a square
//   grid this gives exactly the lattice's (i±2, j), (i, j±2) springs; on a regular
//   triangular lattice the three straight 2h lines (the 60° turns sit at exactly 0.5 and
//   are refused with a 1e-9 margin so rounding cannot let them in).
// A pair is kept once; if it qualifies as two kinds, the first of structural, shear,
// bending wins. Springs whose ends coincide in space (possible only for shear/bending pairs
// of a folded mesh) are skipped, as no spring direction exists.
//
// Stiffness, scaled with element size so that a material means the same at any resolution
// (S = stretch_stiffness, G = shear_stiffness, B = bending_rigidity, all per sheet):
// - structural: k_e = S · A_e / l_e², A_e the area the edge stands for: the whole area of
//   each adjacent triangle face plus half the area of each adjacent quad.
//   Triangles: a triangle of area A giving each edge i the share S·A/l_i² stores, under a
//   uniform strain ε, ½·S·A·Σ_i (n_i·ε·n_i)² (n_i the edge directions). For an equilateral
//   triangle Σ_i (n_i·ε·n_i)² = 3/8·((tr ε)² + 2 ε:ε), so the sheet has Lamé constants
//   λ = μ = 3S/8, Young's modulus (uniaxial stress) 4μ(λ+μ)/(λ+2μ) = S and Poisson ratio
//   1/3: a regular triangular lattice stretches exactly like a sheet of stretch stiffness S
//   (the classic result E = 2k/√3 for springs k, with k = S·(√3/2·l²)/l² = √3/2·S).
//   Quads: a rectangle a×b giving its two a-sides S·(ab/2)/a² each stores ½·S·ab·ε_xx²
//   (and likewise along b): uniaxial stiffness S with no Poisson coupling, as the lattice's
//   structural springs (lattice_panel.h). On a square grid interior edges get exactly S;
//   boundary edges get S/2 (one quad), so a strip of width W pulls S·ε·W exactly, where the
//   lattice panel's full-k boundary adds one extra row (S·ε·(W + h)).
// - shear: k_d = G · 2·A_q / l_d² for a quad's diagonal (A_q the quad's area). On a square
//   cell both diagonals get exactly G and the sheet's shear modulus is G, as on the
//   lattice. A rectangle of aspect a/b gets G·4a²b²/(a²+b²)² (0.64·G at 2:1): softer, but
//   with k bounded by the cell's area; the exact-shear choice k ∝ l_d²/A_q would make thin
//   cells' diagonals arbitrarily stiff in stretch. Across an edge of two triangles of areas
//   A1, A2, the far-vertex spring is the other diagonal of the quadrilateral they form and
//   gets the same rule with A_q = A1 + A2: on a triangulated square cell it is the cell's
//   missing diagonal with k = G, as on the lattice. (On a triangle mesh the triangles already
//   resist shear through their structural springs; these springs add to that.)
// - bending: k_b = B / (l_b/2)², l_b the spring's rest length: the lattice rule B/h² with
//   h = l_b/2, the spacing of the particle being skipped.
// - a material's structural_spring_k / shear_spring_k / bending_spring_k, when > 0,
//   replaces the derived k of every spring of that kind; damping c = material.damping · k.
//
// Masses are lumped: each vertex gets density · ⅓ of the area of every triangle it belongs
// to, quads counting as the two triangles they are split into (along the shorter diagonal,
// or the other one if that leaves a degenerate triangle). The total is density × the mesh
// area exactly. Each vertex's area is the same sum without the density.

#include "sim_core/cloth/mesh_cloth.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <unordered_set>
#include <utility>

#include "sim_core/common/input_error.h"

namespace costume::sim {

namespace {

/// Faces (and each triangle a quad is split into) below this area are refused [m²].
constexpr double kMinFaceArea = 1e-14;
/// Bending springs continue a line within 60°; the margin keeps exact 60° turns out.
constexpr double kBendingMinCosine = 0.5 + 1e-9;

using Vertex = Eigen::Vector3d;

/// The prefix of every error message: "mesh 'x.obj' of garment 'skirt': ".
std::string Where(const SurfaceMesh& mesh, const std::string& name) {
  return "mesh '" + mesh.source + "' of garment '" + name + "': ";
}

std::string FaceField(std::size_t face) { return "faces[" + std::to_string(face) + "]"; }

Vertex Position(const SurfaceMesh& mesh, int v) { return mesh.vertices.row(v).transpose(); }

double TriangleArea(const SurfaceMesh& mesh, int a, int b, int c) {
  return 0.5 * (Position(mesh, b) - Position(mesh, a))
                   .cross(Position(mesh, c) - Position(mesh, a))
                   .norm();
}

/// One triangle of the bookkeeping: a triangle face, or one half of a split quad.
struct Triangle {
  Eigen::Vector3i v;
  /// The mesh face it belongs to.
  int face = 0;
  double area = 0.0;
};

/// Splits a face into 1 or 2 counter-clockwise triangles. A quad is cut along its shorter
/// diagonal (better shaped triangles), unless that leaves a triangle below kMinFaceArea
/// and the other diagonal does not (a quad with three vertices in line).
std::vector<Triangle> SplitFace(const SurfaceMesh& mesh, int face) {
  const std::vector<int>& f = mesh.faces[face];
  auto make = [&](int a, int b, int c) {
    return Triangle{Eigen::Vector3i(f[a], f[b], f[c]), face, TriangleArea(mesh, f[a], f[b], f[c])};
  };
  if (f.size() == 3) return {make(0, 1, 2)};
  std::vector<Triangle> along02 = {make(0, 1, 2), make(0, 2, 3)};
  std::vector<Triangle> along13 = {make(0, 1, 3), make(1, 2, 3)};
  auto min_area = [](const std::vector<Triangle>& t) { return std::min(t[0].area, t[1].area); };
  const bool shorter02 = (Position(mesh, f[2]) - Position(mesh, f[0])).squaredNorm() <=
                         (Position(mesh, f[3]) - Position(mesh, f[1])).squaredNorm();
  std::vector<Triangle>& preferred = shorter02 ? along02 : along13;
  std::vector<Triangle>& other = shorter02 ? along13 : along02;
  if (min_area(preferred) < kMinFaceArea && min_area(other) >= kMinFaceArea) return other;
  return preferred;
}

void ValidateVertices(const SurfaceMesh& mesh, const std::string& where) {
  if (mesh.vertices.rows() == 0) {
    throw InputError(where + "mesh has no vertices: vertices count = 0, allowed >= 3");
  }
  const char* axis[] = {"x", "y", "z"};
  // Before any area is computed: a damaged file's 1e300 was reported as an infinite mass.
  for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v) {
    for (int c = 0; c < 3; ++c) {
      RequireInRange(where + "vertices[" + std::to_string(v) + "]." + axis[c], mesh.vertices(v, c),
                     -kMaxCoordinate, kMaxCoordinate, "m");
    }
  }
}

/// Checks one face's size and indices (geometry is checked once all indices are known good).
void ValidateFaceIndices(const SurfaceMesh& mesh, std::size_t face, const std::string& where) {
  const std::vector<int>& f = mesh.faces[face];
  const std::string field = where + FaceField(face);
  if (f.size() < 3 || f.size() > 4) {
    throw InputError(field + " has " + std::to_string(f.size()) +
                     " vertices: allowed 3 (triangle) or 4 (quad)");
  }
  const auto n = mesh.vertices.rows();
  for (std::size_t k = 0; k < f.size(); ++k) {
    if (f[k] < 0 || f[k] >= n) {
      throw InputError(field + "[" + std::to_string(k) + "] = " + std::to_string(f[k]) +
                       " is out of range: allowed 0 to " + std::to_string(n - 1) +
                       " (the mesh has " + std::to_string(n) + " vertices)");
    }
    for (std::size_t j = 0; j < k; ++j) {
      if (f[j] == f[k]) {
        throw InputError(field + " uses vertex " + std::to_string(f[k]) +
                         " twice: a face needs 3 or 4 distinct vertices");
      }
    }
  }
}

/// Refuses zero-length sides and faces whose triangles have (nearly) no area.
void ValidateFaceGeometry(const SurfaceMesh& mesh, std::size_t face,
                          const std::vector<Triangle>& triangles, const std::string& where) {
  const std::vector<int>& f = mesh.faces[face];
  for (std::size_t k = 0; k < f.size(); ++k) {
    const int a = f[k], b = f[(k + 1) % f.size()];
    const double length = (Position(mesh, b) - Position(mesh, a)).norm();
    if (!(length > 0)) {
      throw InputError(where + FaceField(face) + " edge " + std::to_string(a) + "-" +
                       std::to_string(b) + " length = " + FormatValue(length) +
                       " m (coincident vertices): allowed > 0 m");
    }
  }
  for (const Triangle& t : triangles) {
    if (!(t.area >= kMinFaceArea)) {
      throw InputError(where + FaceField(face) + " area = " + FormatValue(t.area) +
                       " m² (in a triangle " + (f.size() == 4 ? "of the split quad" : "face") +
                       ") is degenerate: allowed >= " + FormatValue(kMinFaceArea) + " m²");
    }
  }
}

/// Validates the mesh and returns its bookkeeping triangles, in face order.
std::vector<Triangle> ValidateAndSplit(const SurfaceMesh& mesh, const std::string& where) {
  ValidateVertices(mesh, where);
  if (mesh.faces.empty()) {
    throw InputError(where + "mesh has no faces: faces count = 0, allowed >= 1");
  }
  for (std::size_t face = 0; face < mesh.faces.size(); ++face) {
    ValidateFaceIndices(mesh, face, where);
  }
  std::vector<Triangle> triangles;
  for (std::size_t face = 0; face < mesh.faces.size(); ++face) {
    std::vector<Triangle> split = SplitFace(mesh, static_cast<int>(face));
    ValidateFaceGeometry(mesh, face, split, where);
    triangles.insert(triangles.end(), split.begin(), split.end());
  }
  return triangles;
}

/// Lumped areas: each vertex gets a third of every triangle it belongs to. Refuses vertices
/// in no face: they would be particles without mass.
Eigen::VectorXd LumpedAreas(const SurfaceMesh& mesh, const std::vector<Triangle>& triangles,
                            const std::string& name) {
  Eigen::VectorXd areas = Eigen::VectorXd::Zero(mesh.vertices.rows());
  for (const Triangle& t : triangles) {
    for (int c = 0; c < 3; ++c) areas[t.v[c]] += t.area / 3.0;
  }
  for (Eigen::Index v = 0; v < areas.size(); ++v) {
    if (areas[v] == 0.0) {
      const std::string garment = "' (garment '" + name + "')";
      throw InputError("vertex " + std::to_string(v) + " of mesh '" + mesh.source + garment +
                       " belongs to no face: every vertex must be in a face (remove unused "
                       "vertices)");
    }
  }
  return areas;
}

std::uint64_t PairKey(int a, int b) {
  const auto lo = static_cast<std::uint64_t>(std::min(a, b));
  const auto hi = static_cast<std::uint64_t>(std::max(a, b));
  return (hi << 32) | lo;
}

/// What the builder knows of one undirected edge of the bookkeeping triangles.
struct Edge {
  /// True for a side of a mesh face (a structural spring); false for a quad's split diagonal.
  bool is_side = false;
  /// The area A_e this edge stands for in the structural rule [m²].
  double structural_area = 0.0;
  /// Indices of the bookkeeping triangles holding this edge.
  std::vector<int> triangles;
};

/// Spring constant of a kind: the material's per-spring override when set, else `derived`.
double SpringConstant(double override_k, double derived) {
  return override_k > 0 ? override_k : derived;
}

/// Builds the springs in order structural, shear, bending, keeping each pair once.
class SpringBuilder {
 public:
  SpringBuilder(const SurfaceMesh& mesh, const Material& material,
                const std::vector<Triangle>& triangles)
      : mesh_(mesh), material_(material), triangles_(triangles) {
    CollectEdges();
  }

  std::vector<Spring> Build() {
    AddStructuralSprings();
    AddQuadDiagonalSprings();
    AddFarVertexSprings();
    AddBendingSprings();
    return std::move(springs_);
  }

 private:
  void CollectEdges() {
    face_areas_.assign(mesh_.faces.size(), 0.0);
    for (const Triangle& t : triangles_) face_areas_[t.face] += t.area;
    for (std::size_t t = 0; t < triangles_.size(); ++t) {
      const Eigen::Vector3i& v = triangles_[t].v;
      for (int c = 0; c < 3; ++c) {
        edges_[std::minmax(v[c], v[(c + 1) % 3])].triangles.push_back(static_cast<int>(t));
      }
    }
    for (std::size_t face = 0; face < mesh_.faces.size(); ++face) {
      const std::vector<int>& f = mesh_.faces[face];
      const double area = FaceArea(static_cast<int>(face));
      // A triangle lends each side its whole area, a quad half of it (see the file comment).
      const double share = f.size() == 3 ? area : area / 2.0;
      for (std::size_t k = 0; k < f.size(); ++k) {
        Edge& edge = edges_[std::minmax(f[k], f[(k + 1) % f.size()])];
        edge.is_side = true;
        edge.structural_area += share;
      }
    }
    neighbours_.resize(mesh_.vertices.rows());
    for (const auto& [pair, edge] : edges_) {
      if (!edge.is_side) continue;
      neighbours_[pair.first].push_back(pair.second);
      neighbours_[pair.second].push_back(pair.first);
    }
    for (std::vector<int>& n : neighbours_) std::sort(n.begin(), n.end());
  }

  double FaceArea(int face) const { return face_areas_[face]; }

  double Distance(int a, int b) const { return (Position(mesh_, b) - Position(mesh_, a)).norm(); }

  void AddSpring(int a, int b, SpringKind kind, double override_k, double derived_k) {
    const double length = Distance(a, b);
    if (!(length > 0) || !used_pairs_.insert(PairKey(a, b)).second) return;
    Spring s;
    s.a = std::min(a, b);
    s.b = std::max(a, b);
    s.kind = kind;
    s.stiffness = SpringConstant(override_k, derived_k);
    s.damping = material_.damping * s.stiffness;
    s.rest_length = length;
    springs_.push_back(s);
  }

  void AddStructuralSprings() {
    for (const auto& [pair, edge] : edges_) {
      if (!edge.is_side) continue;
      const double l = Distance(pair.first, pair.second);
      AddSpring(pair.first, pair.second, SpringKind::kStructural, material_.structural_spring_k,
                material_.stretch_stiffness * edge.structural_area / (l * l));
    }
  }

  /// Shear spring of a quadrilateral's diagonal: k = G · 2·A_q / l_d².
  void AddShearSpring(int a, int b, double quad_area) {
    const double l = Distance(a, b);
    AddSpring(a, b, SpringKind::kShear, material_.shear_spring_k,
              l > 0 ? material_.shear_stiffness * 2.0 * quad_area / (l * l) : 0.0);
  }

  void AddQuadDiagonalSprings() {
    for (std::size_t face = 0; face < mesh_.faces.size(); ++face) {
      const std::vector<int>& f = mesh_.faces[face];
      if (f.size() != 4) continue;
      const double area = FaceArea(static_cast<int>(face));
      AddShearSpring(f[0], f[2], area);
      AddShearSpring(f[1], f[3], area);
    }
  }

  static int FarVertex(const Triangle& t, const std::pair<int, int>& edge) {
    for (int c = 0; c < 3; ++c) {
      if (t.v[c] != edge.first && t.v[c] != edge.second) return t.v[c];
    }
    return t.v[0];  // unreachable for a triangle holding the edge
  }

  bool IsTriangleFace(const Triangle& t) const { return mesh_.faces[t.face].size() == 3; }

  void AddFarVertexSprings() {
    for (const auto& [pair, edge] : edges_) {
      for (std::size_t i = 0; i < edge.triangles.size(); ++i) {
        for (std::size_t j = i + 1; j < edge.triangles.size(); ++j) {
          const Triangle& t1 = triangles_[edge.triangles[i]];
          const Triangle& t2 = triangles_[edge.triangles[j]];
          if (t1.face == t2.face || !(IsTriangleFace(t1) || IsTriangleFace(t2))) continue;
          const int p = FarVertex(t1, pair), q = FarVertex(t2, pair);
          if (p != q) AddShearSpring(p, q, t1.area + t2.area);
        }
      }
    }
  }

  bool AreNeighbours(int a, int b) const {
    return std::binary_search(neighbours_[a].begin(), neighbours_[a].end(), b);
  }

  /// The structural neighbour of u that best continues the line v→u, or -1 if none is
  /// within 60° of it.
  int StraightestContinuation(int v, int u) const {
    const Vertex direction = (Position(mesh_, u) - Position(mesh_, v)).normalized();
    int best = -1;
    double best_cosine = kBendingMinCosine;
    for (int w : neighbours_[u]) {
      if (w == v || AreNeighbours(v, w)) continue;
      const Vertex step = Position(mesh_, w) - Position(mesh_, u);
      const double cosine = direction.dot(step) / step.norm();
      if (cosine > best_cosine) {
        best_cosine = cosine;
        best = w;
      }
    }
    return best;
  }

  void AddBendingSprings() {
    for (int v = 0; v < static_cast<int>(neighbours_.size()); ++v) {
      for (int u : neighbours_[v]) {
        const int w = StraightestContinuation(v, u);
        if (w < 0) continue;
        const double half = Distance(v, w) / 2.0;
        AddSpring(v, w, SpringKind::kBending, material_.bending_spring_k,
                  half > 0 ? material_.bending_rigidity / (half * half) : 0.0);
      }
    }
  }

  const SurfaceMesh& mesh_;
  const Material& material_;
  const std::vector<Triangle>& triangles_;
  /// Edges by (smaller, larger) vertex index; ordered so the springs come out in a fixed order.
  std::map<std::pair<int, int>, Edge> edges_;
  /// Area of each mesh face (the sum of its triangles) [m²].
  std::vector<double> face_areas_;
  /// Structural neighbours of each vertex, sorted.
  std::vector<std::vector<int>> neighbours_;
  std::unordered_set<std::uint64_t> used_pairs_;
  std::vector<Spring> springs_;
};

}  // namespace

ClothModelData BuildMeshCloth(const SurfaceMesh& mesh, const Material& material,
                              const std::string& name) {
  ValidateMaterial(material, "garment '" + name + "' material");
  const std::string where = Where(mesh, name);
  const std::vector<Triangle> triangles = ValidateAndSplit(mesh, where);
  ClothModelData data;
  data.name = name;
  data.rest_positions = mesh.vertices;
  data.areas = LumpedAreas(mesh, triangles, name);
  data.masses = material.density * data.areas;
  data.drag = material.air_drag * data.areas;
  data.springs = SpringBuilder(mesh, material, triangles).Build();
  for (const Triangle& t : triangles) data.triangles.push_back(t.v);
  data.lattice_rows = 0;
  data.lattice_cols = 0;
  return data;
}

SurfaceMesh WeldShortEdges(const SurfaceMesh& mesh, double min_length) {
  RequireNonNegative(mesh.source + ": weld distance", min_length, "m");
  const int n = static_cast<int>(mesh.vertices.rows());
  std::vector<int> parent(n);
  for (int v = 0; v < n; ++v) parent[v] = v;
  auto root = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (const std::vector<int>& face : mesh.faces) {
    for (std::size_t k = 0; k < face.size(); ++k) {
      const int a = face[k], b = face[(k + 1) % face.size()];
      if ((mesh.vertices.row(a) - mesh.vertices.row(b)).norm() < min_length) parent[root(a)] = root(b);
    }
  }
  // Faces in welded vertices, collapsed ones dropped.
  std::vector<std::vector<int>> faces;
  for (const std::vector<int>& face : mesh.faces) {
    std::vector<int> welded;
    for (int v : face) {
      const int r = root(v);
      if (std::find(welded.begin(), welded.end(), r) == welded.end()) welded.push_back(r);
    }
    if (welded.size() >= 3) faces.push_back(std::move(welded));
  }
  // Renumber the vertices still used; each at the mean of the vertices welded into it.
  std::vector<int> index(n, -1);
  std::vector<int> count;
  SurfaceMesh out;
  out.source = mesh.source;
  std::vector<Eigen::Vector3d> sums;
  for (std::vector<int>& face : faces) {
    for (int& v : face) {
      if (index[v] < 0) {
        index[v] = static_cast<int>(sums.size());
        sums.push_back(Eigen::Vector3d::Zero());
        count.push_back(0);
      }
      v = index[v];
    }
  }
  for (int v = 0; v < n; ++v) {
    const int r = index[root(v)];
    if (r < 0) continue;
    sums[r] += mesh.vertices.row(v).transpose();
    ++count[r];
  }
  out.vertices.resize(static_cast<Eigen::Index>(sums.size()), 3);
  for (std::size_t v = 0; v < sums.size(); ++v) out.vertices.row(v) = (sums[v] / count[v]).transpose();
  out.faces = std::move(faces);
  return out;
}

}  // namespace costume::sim
