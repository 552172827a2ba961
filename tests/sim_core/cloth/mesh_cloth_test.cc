#include "sim_core/cloth/mesh_cloth.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/common/input_error.h"

namespace costume::sim {
namespace {

using Pair = std::pair<int, int>;

const double kSqrt3 = std::sqrt(3.0);

Pair Ordered(int a, int b) { return {std::min(a, b), std::max(a, b)}; }

/// An nx×ny grid of quads' corners: vertex (i, j) (row i, column j) at (j·hx, i·hy, 0),
/// index i·nx + j; quads counter-clockwise seen from +z.
SurfaceMesh QuadGrid(int nx, int ny, double hx, double hy) {
  SurfaceMesh mesh;
  mesh.source = "grid.obj";
  mesh.vertices.resize(nx * ny, 3);
  for (int i = 0; i < ny; ++i) {
    for (int j = 0; j < nx; ++j) mesh.vertices.row(i * nx + j) << j * hx, i * hy, 0.0;
  }
  for (int i = 0; i + 1 < ny; ++i) {
    for (int j = 0; j + 1 < nx; ++j) {
      mesh.faces.push_back({i * nx + j, i * nx + j + 1, (i + 1) * nx + j + 1, (i + 1) * nx + j});
    }
  }
  return mesh;
}

/// An m×m parallelogram of a regular triangular lattice of spacing l: vertex (i, j) at
/// i·a1 + j·a2 with a1 = (l, 0), a2 = (l/2, l√3/2), index j·m + i; two equilateral
/// triangles per cell.
SurfaceMesh TriangularLattice(int m, double l) {
  SurfaceMesh mesh;
  mesh.source = "lattice.obj";
  mesh.vertices.resize(m * m, 3);
  for (int j = 0; j < m; ++j) {
    for (int i = 0; i < m; ++i)
      mesh.vertices.row(j * m + i) << l * (i + 0.5 * j), l * kSqrt3 / 2 * j, 0;
  }
  auto index = [m](int i, int j) { return j * m + i; };
  for (int j = 0; j + 1 < m; ++j) {
    for (int i = 0; i + 1 < m; ++i) {
      mesh.faces.push_back({index(i, j), index(i + 1, j), index(i, j + 1)});
      mesh.faces.push_back({index(i + 1, j), index(i + 1, j + 1), index(i, j + 1)});
    }
  }
  return mesh;
}

/// A regular hexagon of side l as a fan of 6 equilateral triangles: centre 0, rim 1..6.
SurfaceMesh HexagonFan(double l) {
  SurfaceMesh mesh;
  mesh.source = "hexagon.obj";
  mesh.vertices.resize(7, 3);
  mesh.vertices.row(0) << 0, 0, 0;
  for (int r = 0; r < 6; ++r) {
    mesh.vertices.row(r + 1) << l * std::cos(r * std::numbers::pi / 3),
        l * std::sin(r * std::numbers::pi / 3), 0;
    mesh.faces.push_back({0, r + 1, (r + 1) % 6 + 1});
  }
  return mesh;
}

std::set<Pair> PairsOfKind(const ClothModelData& data, SpringKind kind) {
  std::set<Pair> pairs;
  for (const Spring& s : data.springs) {
    if (s.kind == kind) pairs.insert(Ordered(s.a, s.b));
  }
  return pairs;
}

int CountOfKind(const ClothModelData& data, SpringKind kind) {
  int count = 0;
  for (const Spring& s : data.springs) count += s.kind == kind ? 1 : 0;
  return count;
}

/// Elastic energy of the springs of `kind` when the rest shape is deformed by the uniform
/// small in-plane strain `strain` (linearised: each spring stretches by l·nᵀ·strain·n).
double StrainEnergy(const ClothModelData& data, SpringKind kind, const Eigen::Matrix2d& strain) {
  double energy = 0.0;
  for (const Spring& s : data.springs) {
    if (s.kind != kind) continue;
    const Eigen::Vector2d d =
        (data.rest_positions.row(s.b) - data.rest_positions.row(s.a)).head<2>().transpose();
    const double stretch = d.dot(strain * d) / d.norm();
    energy += 0.5 * s.stiffness * stretch * stretch;
  }
  return energy;
}

TEST(BuildMeshCloth, QuadGridHasHandCountedSprings) {
  const int n = 6;
  const ClothModelData data = BuildMeshCloth(QuadGrid(n, n, 0.1, 0.1), Material{}, "square");
  EXPECT_EQ(CountOfKind(data, SpringKind::kStructural), 2 * n * (n - 1));
  EXPECT_EQ(CountOfKind(data, SpringKind::kShear), 2 * (n - 1) * (n - 1));
  EXPECT_EQ(CountOfKind(data, SpringKind::kBending), 2 * n * (n - 2));
  EXPECT_EQ(data.triangles.size(), std::size_t{2 * (n - 1) * (n - 1)});
}

TEST(BuildMeshCloth, SquareGridGetsLatticeBendingSprings) {
  const int n = 7;
  const ClothModelData data = BuildMeshCloth(QuadGrid(n, n, 0.05, 0.05), Material{}, "square");
  std::set<Pair> expected;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      if (j + 2 < n) expected.insert({i * n + j, i * n + j + 2});
      if (i + 2 < n) expected.insert({i * n + j, (i + 2) * n + j});
    }
  }
  EXPECT_EQ(PairsOfKind(data, SpringKind::kBending), expected);
}

TEST(BuildMeshCloth, SquareGridGetsBothDiagonalsAsShearSprings) {
  const int n = 5;
  const ClothModelData data = BuildMeshCloth(QuadGrid(n, n, 0.05, 0.05), Material{}, "square");
  std::set<Pair> expected;
  for (int i = 0; i + 1 < n; ++i) {
    for (int j = 0; j + 1 < n; ++j) {
      expected.insert({i * n + j, (i + 1) * n + j + 1});
      expected.insert({i * n + j + 1, (i + 1) * n + j});
    }
  }
  EXPECT_EQ(PairsOfKind(data, SpringKind::kShear), expected);
}

TEST(BuildMeshCloth, SquareGridSpringsHaveLatticeStiffnessAndRestLength) {
  const int n = 5;
  const double h = 0.04;
  Material material;
  material.stretch_stiffness = 800;
  material.shear_stiffness = 300;
  material.bending_rigidity = 2e-5;
  material.damping = 0.01;
  const ClothModelData data = BuildMeshCloth(QuadGrid(n, n, h, h), material, "square");
  auto on_boundary = [n](int v) {
    return v / n == 0 || v / n == n - 1 || v % n == 0 || v % n == n - 1;
  };
  for (const Spring& s : data.springs) {
    SCOPED_TRACE(std::string(SpringKindName(s.kind)) + " " + std::to_string(s.a) + "-" +
                 std::to_string(s.b));
    switch (s.kind) {
      case SpringKind::kStructural:
        EXPECT_NEAR(s.rest_length, h, 1e-15);
        // A boundary edge stands for one quad, half the sheet strip of an interior edge.
        EXPECT_NEAR(s.stiffness, on_boundary(s.a) && on_boundary(s.b) ? 400.0 : 800.0, 1e-9);
        break;
      case SpringKind::kShear:
        EXPECT_NEAR(s.rest_length, h * std::sqrt(2.0), 1e-15);
        EXPECT_NEAR(s.stiffness, 300.0, 1e-9);
        break;
      case SpringKind::kBending:
        EXPECT_NEAR(s.rest_length, 2 * h, 1e-15);
        EXPECT_NEAR(s.stiffness, 2e-5 / (h * h), 1e-12);
        break;
    }
    EXPECT_NEAR(s.damping, 0.01 * s.stiffness, 1e-12);
  }
}

TEST(BuildMeshCloth, RectangularQuadSheetStretchesWithStretchStiffness) {
  // Uniaxial strain e of a sheet of stretch stiffness S (no Poisson coupling, as on the
  // lattice) stores ½·S·e²·area, whatever the cell shape.
  const int nx = 6, ny = 4;
  const double hx = 0.1, hy = 0.05, e = 1e-3;
  Material material;
  material.stretch_stiffness = 500;
  const ClothModelData data = BuildMeshCloth(QuadGrid(nx, ny, hx, hy), material, "sheet");
  const double area = (nx - 1) * hx * (ny - 1) * hy;
  EXPECT_NEAR(StrainEnergy(data, SpringKind::kStructural, Eigen::Vector2d(e, 0).asDiagonal()),
              0.5 * 500 * e * e * area, 1e-12 * 500 * e * e * area);
  EXPECT_NEAR(StrainEnergy(data, SpringKind::kStructural, Eigen::Vector2d(0, e).asDiagonal()),
              0.5 * 500 * e * e * area, 1e-12 * 500 * e * e * area);
}

TEST(BuildMeshCloth, SquareQuadSheetShearsWithShearStiffness) {
  // Engineering shear γ of a sheet of shear modulus G stores ½·G·γ²·area.
  const int n = 6;
  const double h = 0.1, gamma = 2e-3;
  Material material;
  material.shear_stiffness = 250;
  const ClothModelData data = BuildMeshCloth(QuadGrid(n, n, h, h), material, "sheet");
  Eigen::Matrix2d strain;
  strain << 0, gamma / 2, gamma / 2, 0;
  const double area = (n - 1) * h * (n - 1) * h;
  const double expected = 0.5 * 250 * gamma * gamma * area;
  EXPECT_NEAR(StrainEnergy(data, SpringKind::kShear, strain), expected, 1e-12 * expected);
}

TEST(BuildMeshCloth, TriangularLatticeHasHandCountedSprings) {
  // m×m parallelogram: edges along a1 and a2 m(m−1) each, cell diagonals (m−1)², of which
  // 4(m−1) on the boundary; one far-vertex spring per interior edge; straight 2l lines along
  // a1 and a2 m(m−2) each and along a2−a1 (m−2)².
  const int m = 5;
  const ClothModelData data = BuildMeshCloth(TriangularLattice(m, 0.1), Material{}, "lattice");
  const int edges = 2 * m * (m - 1) + (m - 1) * (m - 1);
  EXPECT_EQ(CountOfKind(data, SpringKind::kStructural), edges);
  EXPECT_EQ(CountOfKind(data, SpringKind::kShear), edges - 4 * (m - 1));
  EXPECT_EQ(CountOfKind(data, SpringKind::kBending), 2 * m * (m - 2) + (m - 2) * (m - 2));
  for (const Spring& s : data.springs) {
    const double expected_length = s.kind == SpringKind::kStructural ? 0.1
                                   : s.kind == SpringKind::kShear    ? 0.1 * kSqrt3
                                                                     : 0.2;
    EXPECT_NEAR(s.rest_length, expected_length, 1e-14) << SpringKindName(s.kind);
  }
}

TEST(BuildMeshCloth, TriangularLatticeStretchesLikeIsotropicSheetOfStretchStiffness) {
  // A sheet with Young's modulus S and Poisson ratio 1/3 has Lamé constants λ = μ = 3S/8:
  // energy density ½λ(tr ε)² + μ ε:ε, i.e. 9S/16·e² under uniaxial strain e and
  // 3S/4·g² under pure shear ε_xy = g.
  const int m = 6;
  const double l = 0.05, S = 1200.0, e = 1e-3;
  Material material;
  material.stretch_stiffness = S;
  const ClothModelData data = BuildMeshCloth(TriangularLattice(m, l), material, "lattice");
  const double area = 2 * (m - 1) * (m - 1) * kSqrt3 / 4 * l * l;
  const double uniaxial = 9 * S / 16 * e * e * area;
  EXPECT_NEAR(StrainEnergy(data, SpringKind::kStructural, Eigen::Vector2d(e, 0).asDiagonal()),
              uniaxial, 1e-12 * uniaxial);
  EXPECT_NEAR(StrainEnergy(data, SpringKind::kStructural, Eigen::Vector2d(0, e).asDiagonal()),
              uniaxial, 1e-12 * uniaxial);
  Eigen::Matrix2d shear;
  shear << 0, e, e, 0;
  EXPECT_NEAR(StrainEnergy(data, SpringKind::kStructural, shear), 3 * S / 4 * e * e * area,
              1e-12 * uniaxial);
}

TEST(BuildMeshCloth, HexagonFanGetsFarVertexShearAndStraightBending) {
  const double l = 0.1, S = 1000.0, G = 600.0, B = 3e-5;
  Material material;
  material.stretch_stiffness = S;
  material.shear_stiffness = G;
  material.bending_rigidity = B;
  const ClothModelData data = BuildMeshCloth(HexagonFan(l), material, "hexagon");
  EXPECT_EQ(CountOfKind(data, SpringKind::kStructural), 12);
  const std::set<Pair> shear = {{1, 3}, {2, 4}, {3, 5}, {4, 6}, {1, 5}, {2, 6}};
  EXPECT_EQ(PairsOfKind(data, SpringKind::kShear), shear);
  const std::set<Pair> bending = {{1, 4}, {2, 5}, {3, 6}};
  EXPECT_EQ(PairsOfKind(data, SpringKind::kBending), bending);
  for (const Spring& s : data.springs) {
    SCOPED_TRACE(std::to_string(s.a) + "-" + std::to_string(s.b));
    if (s.kind == SpringKind::kStructural) {
      // Spokes stand for two triangles of area √3/4·l², rim edges for one.
      EXPECT_NEAR(s.stiffness, s.a == 0 ? S * kSqrt3 / 2 : S * kSqrt3 / 4, 1e-9);
    } else if (s.kind == SpringKind::kShear) {
      // Diagonal √3·l of a rhombus of area √3/2·l²: G·2·(√3/2·l²)/(3l²).
      EXPECT_NEAR(s.stiffness, G / kSqrt3, 1e-9);
    } else {
      EXPECT_NEAR(s.stiffness, B / (l * l), 1e-12);
    }
  }
}

TEST(BuildMeshCloth, LumpedMassesAddUpToDensityTimesArea) {
  Material material;
  material.density = 0.23;
  const double triangle = kSqrt3 / 4 * 0.1 * 0.1;
  const ClothModelData hexagon = BuildMeshCloth(HexagonFan(0.1), material, "hexagon");
  EXPECT_NEAR(hexagon.masses.sum(), 0.23 * 6 * triangle, 1e-15);
  EXPECT_NEAR(hexagon.masses[0], 0.23 * 2 * triangle, 1e-15);
  for (int r = 1; r <= 6; ++r) EXPECT_NEAR(hexagon.masses[r], 0.23 * 2 * triangle / 3, 1e-15);
  EXPECT_NEAR(hexagon.areas.sum(), 6 * triangle, 1e-15);

  const ClothModelData grid = BuildMeshCloth(QuadGrid(5, 4, 0.1, 0.2), material, "grid");
  EXPECT_NEAR(grid.masses.sum(), 0.23 * 0.4 * 0.6, 1e-14);
  EXPECT_NEAR(grid.areas.sum(), 0.4 * 0.6, 1e-14);

  const ClothModelData lattice = BuildMeshCloth(TriangularLattice(4, 0.1), material, "lattice");
  EXPECT_NEAR(lattice.masses.sum(), 0.23 * 18 * triangle, 1e-14);
}

TEST(BuildMeshCloth, QuadIsSplitAlongItsShorterDiagonal) {
  SurfaceMesh mesh;
  mesh.source = "quad.obj";
  mesh.vertices.resize(4, 3);
  // Diagonal 0–2 is √10 long, 1–3 is √2.
  mesh.vertices << 0, 0, 0, 2, 0, 0, 3, 1, 0, 1, 1, 0;
  mesh.faces = {{0, 1, 2, 3}};
  const ClothModelData data = BuildMeshCloth(mesh, Material{}, "quad");
  ASSERT_EQ(data.triangles.size(), 2u);
  EXPECT_EQ(data.triangles[0], Eigen::Vector3i(0, 1, 3));
  EXPECT_EQ(data.triangles[1], Eigen::Vector3i(1, 2, 3));
  EXPECT_EQ(CountOfKind(data, SpringKind::kStructural), 4);
  EXPECT_EQ(PairsOfKind(data, SpringKind::kShear), (std::set<Pair>{{0, 2}, {1, 3}}));
}

TEST(BuildMeshCloth, QuadWithThreeVerticesInLineIsSplitThroughTheMiddleOne) {
  SurfaceMesh mesh;
  mesh.source = "quad.obj";
  mesh.vertices.resize(4, 3);
  // 0, 1, 2 in line: the shorter diagonal 0–2 would leave a zero-area triangle.
  mesh.vertices << 0, 0, 0, 1, 0, 0, 2, 0, 0, 1, 3, 0;
  mesh.faces = {{0, 1, 2, 3}};
  const ClothModelData data = BuildMeshCloth(mesh, Material{}, "quad");
  ASSERT_EQ(data.triangles.size(), 2u);
  EXPECT_EQ(data.triangles[0], Eigen::Vector3i(0, 1, 3));
  EXPECT_EQ(data.triangles[1], Eigen::Vector3i(1, 2, 3));
  EXPECT_NEAR(data.masses.sum(), Material{}.density * 3.0, 1e-15);
}

TEST(BuildMeshCloth, TriangleBesideQuadGetsShearSpringAcrossTheSharedEdge) {
  SurfaceMesh mesh;
  mesh.source = "mixed.obj";
  mesh.vertices.resize(5, 3);
  mesh.vertices << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 0.5, 0;
  mesh.faces = {{0, 1, 2, 3}, {1, 4, 2}};
  const ClothModelData data = BuildMeshCloth(mesh, Material{}, "mixed");
  EXPECT_EQ(CountOfKind(data, SpringKind::kStructural), 6);
  // The quad's two diagonals and the far-vertex spring from 4 across edge 1–2.
  const std::set<Pair> shear = PairsOfKind(data, SpringKind::kShear);
  EXPECT_EQ(shear.size(), 3u);
  EXPECT_TRUE(shear.count({0, 4}) + shear.count({3, 4}) == 1);
  EXPECT_EQ(data.triangles.size(), 3u);
}

TEST(BuildMeshCloth, TriangulatedSquareCellGetsItsOtherDiagonalWithShearStiffness) {
  SurfaceMesh mesh;
  mesh.source = "cell.obj";
  mesh.vertices.resize(4, 3);
  mesh.vertices << 0, 0, 0, 0.1, 0, 0, 0.1, 0.1, 0, 0, 0.1, 0;
  mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  Material material;
  material.stretch_stiffness = 900;
  material.shear_stiffness = 350;
  const ClothModelData data = BuildMeshCloth(mesh, material, "cell");
  ASSERT_EQ(PairsOfKind(data, SpringKind::kShear), (std::set<Pair>{{1, 3}}));
  for (const Spring& s : data.springs) {
    if (s.kind == SpringKind::kShear) {
      EXPECT_NEAR(s.stiffness, 350.0, 1e-9);
    }
    // The diagonal edge 0–2 (length h√2) stands for both triangles (area h²): S·h²/(2h²).
    if (s.kind == SpringKind::kStructural && s.a == 0 && s.b == 2) {
      EXPECT_NEAR(s.stiffness, 450.0, 1e-9);
    }
  }
  EXPECT_EQ(CountOfKind(data, SpringKind::kStructural), 5);
  EXPECT_EQ(CountOfKind(data, SpringKind::kBending), 0);
}

TEST(BuildMeshCloth, MaterialSpringConstantsOverrideDerivedStiffness) {
  Material material;
  material.structural_spring_k = 147;
  material.shear_spring_k = 76;
  material.bending_spring_k = 4.9;
  material.damping = 0.002;
  const ClothModelData data = BuildMeshCloth(QuadGrid(5, 5, 0.1, 0.1), material, "blender");
  for (const Spring& s : data.springs) {
    const double k = s.kind == SpringKind::kStructural ? 147
                     : s.kind == SpringKind::kShear    ? 76
                                                       : 4.9;
    EXPECT_EQ(s.stiffness, k) << SpringKindName(s.kind);
    EXPECT_NEAR(s.damping, 0.002 * k, 1e-15);
  }
}

TEST(BuildMeshCloth, ResultIsAValidClothModelWithoutLatticeOrPins) {
  const ClothModelData data = BuildMeshCloth(TriangularLattice(5, 0.1), Material{}, "scarf");
  EXPECT_EQ(data.name, "scarf");
  EXPECT_EQ(data.lattice_rows, 0);
  EXPECT_EQ(data.lattice_cols, 0);
  EXPECT_TRUE(data.pinned.empty());
  EXPECT_EQ(data.rest_positions, TriangularLattice(5, 0.1).vertices);
  const auto model = ClothModel::Create(data);
  EXPECT_EQ(model->num_particles(), 25);
}

// ---- refusals ------------------------------------------------------------------------------

/// A unit right triangle (vertices 0, 1, 2) named x.obj, to be broken by each test.
SurfaceMesh SmallMesh() {
  SurfaceMesh mesh;
  mesh.source = "x.obj";
  mesh.vertices.resize(3, 3);
  mesh.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  mesh.faces = {{0, 1, 2}};
  return mesh;
}

/// Expects BuildMeshCloth to refuse `mesh` with a message naming the source, the garment
/// and every one of `fragments`.
void ExpectRefused(const SurfaceMesh& mesh, const std::vector<std::string>& fragments,
                   const Material& material = Material{}) {
  try {
    BuildMeshCloth(mesh, material, "skirt");
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("x.obj"), std::string::npos) << message;
    EXPECT_NE(message.find("skirt"), std::string::npos) << message;
    for (const std::string& fragment : fragments) {
      EXPECT_NE(message.find(fragment), std::string::npos) << "'" << fragment << "' in " << message;
    }
  }
}

TEST(BuildMeshCloth, RefusesMeshWithoutVertices) {
  SurfaceMesh mesh = SmallMesh();
  mesh.vertices.resize(0, 3);
  mesh.faces.clear();
  ExpectRefused(mesh, {"no vertices", "vertices count = 0"});
}

TEST(BuildMeshCloth, RefusesMeshWithoutFaces) {
  SurfaceMesh mesh = SmallMesh();
  mesh.faces.clear();
  ExpectRefused(mesh, {"mesh has no faces", "faces count = 0"});
}

TEST(BuildMeshCloth, RefusesFaceOfTwoVertices) {
  SurfaceMesh mesh = SmallMesh();
  mesh.faces.push_back({0, 1});
  ExpectRefused(mesh, {"faces[1]", "has 2 vertices", "allowed 3"});
}

TEST(BuildMeshCloth, RefusesFaceOfFiveVertices) {
  SurfaceMesh mesh = SmallMesh();
  mesh.faces = {{0, 1, 2, 0, 1}};
  ExpectRefused(mesh, {"faces[0]", "has 5 vertices", "allowed 3"});
}

TEST(BuildMeshCloth, RefusesIndexOutOfRange) {
  SurfaceMesh mesh = SmallMesh();
  mesh.faces = {{0, 1, 9}};
  ExpectRefused(mesh, {"faces[0][2] = 9", "allowed 0 to 2"});
  mesh.faces = {{0, -1, 2}};
  ExpectRefused(mesh, {"faces[0][1] = -1", "allowed 0 to 2"});
}

TEST(BuildMeshCloth, RefusesFaceUsingAVertexTwice) {
  SurfaceMesh mesh = SmallMesh();
  mesh.faces = {{0, 1, 1}};
  ExpectRefused(mesh, {"faces[0]", "vertex 1 twice"});
}

TEST(BuildMeshCloth, RefusesDegenerateFace) {
  SurfaceMesh mesh = SmallMesh();
  mesh.vertices.row(2) << 2, 0, 0;  // in line with 0 and 1
  ExpectRefused(mesh, {"faces[0] area = 0", "degenerate", "1e-14"});
  SurfaceMesh sliver = SmallMesh();
  sliver.vertices.row(2) << 0.5, 1e-15, 0;
  ExpectRefused(sliver, {"faces[0] area", "degenerate"});
}

TEST(BuildMeshCloth, RefusesEdgeBetweenCoincidentVertices) {
  SurfaceMesh mesh = SmallMesh();
  mesh.vertices.row(2) = mesh.vertices.row(1);
  ExpectRefused(mesh, {"faces[0] edge 1-2 length = 0", "coincident"});
}

TEST(BuildMeshCloth, RefusesNonFiniteAndFarCoordinates) {
  SurfaceMesh mesh = SmallMesh();
  mesh.vertices(1, 1) = std::numeric_limits<double>::quiet_NaN();
  ExpectRefused(mesh, {"vertices[1].y = nan"});
  mesh.vertices(1, 1) = std::numeric_limits<double>::infinity();
  ExpectRefused(mesh, {"vertices[1].y = inf"});
  // Beyond any stage (a damaged file): named, not read as an infinite particle mass.
  mesh.vertices(1, 1) = 1e300;
  ExpectRefused(mesh, {"mesh 'x.obj'", "vertices[1].y = 1e+300 m", "-10000"});
}

TEST(BuildMeshCloth, RefusesVertexInNoFace) {
  SurfaceMesh mesh = SmallMesh();
  mesh.vertices.conservativeResize(4, 3);
  mesh.vertices.row(3) << 5, 5, 0;
  ExpectRefused(mesh, {"vertex 3 of mesh 'x.obj'", "belongs to no face"});
}

TEST(BuildMeshCloth, RefusesBadMaterialNamingTheGarment) {
  Material material;
  material.density = -1;
  EXPECT_THROW(BuildMeshCloth(SmallMesh(), material, "skirt"), InputError);
  try {
    BuildMeshCloth(SmallMesh(), material, "skirt");
  } catch (const InputError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("garment 'skirt'"), std::string::npos) << message;
    EXPECT_NE(message.find("density"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace costume::sim

namespace costume::sim {
namespace {

// Two unit quads side by side, the middle edge's top end 0.5 mm from a fourth vertex placed
// beside it: welding at 1 mm joins exactly those two, the quad that held both becomes a
// triangle, nothing else moves (counted and located by hand).
TEST(WeldShortEdges, JoinsTheEndsOfShortEdgesAndDropsWhatCollapses) {
  SurfaceMesh mesh;
  mesh.source = "weld test";
  mesh.vertices.resize(7, 3);
  mesh.vertices << 0, 0, 0,  1, 0, 0,  2, 0, 0,  0, 0, 1,  1, 0, 1,  2, 0, 1,  1.0005, 0, 1;
  mesh.faces = {{0, 1, 4, 3}, {1, 2, 5, 6}, {1, 6, 4}};
  const SurfaceMesh welded = WeldShortEdges(mesh, 0.001);
  EXPECT_EQ(welded.vertices.rows(), 6);
  ASSERT_EQ(welded.faces.size(), 2u);  // the sliver triangle (1, 6, 4) collapsed
  EXPECT_EQ(welded.faces[0].size(), 4u);
  EXPECT_EQ(welded.faces[1].size(), 4u);
  double x_sum = 0.0;
  for (Eigen::Index v = 0; v < welded.vertices.rows(); ++v) x_sum += welded.vertices(v, 0);
  EXPECT_NEAR(x_sum, 0 + 1 + 2 + 0 + 2 + 1.00025, 1e-12);  // 4 and 6 met half-way
  EXPECT_EQ(WeldShortEdges(mesh, 0.0).vertices.rows(), 7);
  EXPECT_THROW(WeldShortEdges(mesh, -1.0), InputError);
}

}  // namespace
}  // namespace costume::sim
