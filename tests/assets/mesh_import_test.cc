#include "assets/mesh_import.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/cloth/mesh_cloth.h"
#include "sim_core/common/input_error.h"
#include "tests/assets/import_test_support.h"

namespace costume::assets {
namespace {

namespace fs = std::filesystem;
using sim::InputError;
using sim::SurfaceMesh;
using testing::ScratchDir;

const char* kQuadObj =
    "# a unit square\n"
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    "f 1 2 3 4\n";

const char* kTwoTrianglesObj =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    "f 1 2 3\nf 1 3 4\n";

const char* kPentagonObj =
    "v 1 0 0\nv 0.309 0.951 0\nv -0.809 0.588 0\nv -0.809 -0.588 0\nv 0.309 -0.951 0\n"
    "f 1 2 3 4 5\n";

/// Two quads side by side in two OBJ objects with their own texture coordinates: the
/// shared edge's vertices appear with different UVs in each.
const char* kSeamObj =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
    "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n"
    "o left\nf 1/1 2/2 3/3 4/4\n"
    "o right\nf 2/5 5/2 6/3 3/5\n";

/// A 2×1 strip whose faces come before the vertices they use (assimp accepts that order),
/// so that its first half holds faces naming vertices that are not in it.
const char* kFacesFirstObj =
    "f 1 2 3 4\nf 2 5 6 3\n"
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n";

/// Expects `call` to throw InputError whose message holds each of `fragments`.
template <typename Call>
void ExpectRefused(Call call, const std::vector<std::string>& fragments) {
  try {
    call();
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& error) {
    const std::string message = error.what();
    for (const std::string& fragment : fragments) {
      EXPECT_NE(message.find(fragment), std::string::npos) << "'" << fragment << "' in " << message;
    }
  }
}

TEST(ImportSurfaceMesh, KeepsTheQuadOfAnObjFile) {
  ScratchDir dir;
  const std::string path = dir.Write("quad.obj", kQuadObj);
  const SurfaceMesh mesh = ImportSurfaceMesh(path, {});
  EXPECT_EQ(mesh.source, path);
  ASSERT_EQ(mesh.vertices.rows(), 4);
  ASSERT_EQ(mesh.faces.size(), 1u);
  ASSERT_EQ(mesh.faces[0].size(), 4u);
  // Face order is kept: 1 2 3 4 of the file.
  const double expected[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (int k = 0; k < 4; ++k) {
    for (int c = 0; c < 3; ++c) EXPECT_EQ(mesh.vertices(mesh.faces[0][k], c), expected[k][c]);
  }
}

TEST(ImportSurfaceMesh, ReadsTwoTrianglesSharingTheirVertices) {
  ScratchDir dir;
  const SurfaceMesh mesh = ImportSurfaceMesh(dir.Write("tris.obj", kTwoTrianglesObj), {});
  EXPECT_EQ(mesh.vertices.rows(), 4);
  ASSERT_EQ(mesh.faces.size(), 2u);
  EXPECT_EQ(mesh.faces[0].size(), 3u);
  EXPECT_EQ(mesh.faces[1].size(), 3u);
}

TEST(ImportSurfaceMesh, CutsPolygonOfFiveVerticesIntoAFanOfTriangles) {
  ScratchDir dir;
  const SurfaceMesh mesh = ImportSurfaceMesh(dir.Write("pentagon.obj", kPentagonObj), {});
  EXPECT_EQ(mesh.vertices.rows(), 5);
  ASSERT_EQ(mesh.faces.size(), 3u);
  for (const std::vector<int>& face : mesh.faces) {
    ASSERT_EQ(face.size(), 3u);
    EXPECT_EQ(face[0], mesh.faces[0][0]);  // every triangle starts at the first vertex
    // Counter-clockwise from +z, as the pentagon.
    const Eigen::Vector3d a = mesh.vertices.row(face[0]).transpose();
    const Eigen::Vector3d b = mesh.vertices.row(face[1]).transpose();
    const Eigen::Vector3d c = mesh.vertices.row(face[2]).transpose();
    EXPECT_GT((b - a).cross(c - a).z(), 0);
  }
}

TEST(ImportSurfaceMesh, ScalesThenAddsTheOffset) {
  ScratchDir dir;
  MeshImportOptions options;
  options.scale = 0.1;
  options.offset = Eigen::Vector3d(1.0, -2.0, 0.5);
  const SurfaceMesh mesh = ImportSurfaceMesh(dir.Write("quad.obj", kQuadObj), options);
  ASSERT_EQ(mesh.vertices.rows(), 4);
  std::set<std::vector<double>> corners;
  for (int v = 0; v < 4; ++v) {
    corners.insert({mesh.vertices(v, 0), mesh.vertices(v, 1), mesh.vertices(v, 2)});
  }
  const std::set<std::vector<double>> expected = {
      {1.0, -2.0, 0.5}, {1.1, -2.0, 0.5}, {1.1, -1.9, 0.5}, {1.0, -1.9, 0.5}};
  ASSERT_EQ(corners.size(), 4u);
  for (auto got = corners.begin(), want = expected.begin(); got != corners.end(); ++got, ++want) {
    for (int c = 0; c < 3; ++c) EXPECT_NEAR((*got)[c], (*want)[c], 1e-12);
  }
}

TEST(ImportSurfaceMesh, JoinsVerticesSplitByTextureSeamsAndObjects) {
  ScratchDir dir;
  const SurfaceMesh mesh = ImportSurfaceMesh(dir.Write("seam.obj", kSeamObj), {});
  EXPECT_EQ(mesh.vertices.rows(), 6);
  ASSERT_EQ(mesh.faces.size(), 2u);
  // The two quads share an edge, so the cloth is connected.
  const std::set<int> left(mesh.faces[0].begin(), mesh.faces[0].end());
  int shared = 0;
  for (int v : mesh.faces[1]) shared += static_cast<int>(left.count(v));
  EXPECT_EQ(shared, 2);
}

TEST(ImportSurfaceMesh, RefusesScaleThatIsNotPositiveAndFinite) {
  ScratchDir dir;
  const std::string path = dir.Write("quad.obj", kQuadObj);
  for (double scale : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                       std::numeric_limits<double>::infinity()}) {
    MeshImportOptions options;
    options.scale = scale;
    ExpectRefused([&] { ImportSurfaceMesh(path, options); }, {path, "scale = ", "> 0"});
  }
  MeshImportOptions options;
  options.offset.y() = std::numeric_limits<double>::quiet_NaN();
  ExpectRefused([&] { ImportSurfaceMesh(path, options); }, {path, "offset.y = nan"});
}

TEST(ImportSurfaceMesh, RefusesMissingFile) {
  const std::string path = "no/such/folder/missing.obj";
  ExpectRefused([&] { ImportSurfaceMesh(path, {}); }, {path, "no such file"});
  const std::string folder = fs::temp_directory_path().string();  // told apart from a typo
  ExpectRefused([&] { ImportSurfaceMesh(folder, {}); },
                {folder, "cannot read the mesh file: not a regular file"});
}

TEST(ImportSurfaceMesh, RefusesEmptyFile) {
  ScratchDir dir;
  const std::string path = dir.Write("empty.obj", "");
  ExpectRefused([&] { ImportSurfaceMesh(path, {}); }, {path, "cannot read"});
}

TEST(ImportSurfaceMesh, RefusesGarbageBytes) {
  ScratchDir dir;
  std::mt19937 random(20240501);
  std::string bytes(4096, '\0');
  for (char& byte : bytes) byte = static_cast<char>(random() & 0xff);
  const std::string path = dir.Write("x.obj", bytes);
  ExpectRefused([&] { ImportSurfaceMesh(path, {}); }, {path});
}

TEST(ImportSurfaceMesh, RefusesTruncatedFileWhoseFacesNameMissingVertices) {
  ScratchDir dir;
  const std::string whole = kFacesFirstObj;
  // The whole file is fine: the failure below is the truncation's.
  EXPECT_EQ(ImportSurfaceMesh(dir.Write("whole.obj", whole), {}).faces.size(), 2u);
  const std::string path = dir.Write("half.obj", whole.substr(0, whole.size() / 2));
  ExpectRefused([&] { ImportSurfaceMesh(path, {}); }, {path, "vertex index out of range"});
}

// Found by mutating a real garment OBJ: "nan", "inf" or 1e308 (beyond assimp's floats) in a
// vertex came back as a non-finite position.
TEST(ImportSurfaceMesh, RefusesVerticesAtNoFinitePoint) {
  ScratchDir dir;
  for (const char* number : {"nan", "inf", "1e308"}) {
    const std::string path =
        dir.Write("far.obj", std::string("v 0 0 0\nv 1 0 0\nv 1 ") + number + " 0\nf 1 2 3\n");
    ExpectRefused([&] { ImportSurfaceMesh(path, {}); },
                  {path, "vertex 2 at (1, ", "not a finite point"});
  }
  // A finite file coordinate that the scale takes beyond a double's range.
  MeshImportOptions huge;
  huge.scale = 1e300;
  const std::string path = dir.Write("big.obj", "v 0 0 0\nv 1 0 0\nv 1 1e30 0\nf 1 2 3\n");
  ExpectRefused([&] { ImportSurfaceMesh(path, huge); },
                {path, "vertex 2 at (1, 1e+30, 0)", "not a finite point"});
}

TEST(ImportSurfaceMesh, RefusesMeshOfPointsOnly) {
  ScratchDir dir;
  const std::string path = dir.Write("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\np 1 2 3\n");
  ExpectRefused([&] { ImportSurfaceMesh(path, {}); }, {path, "mesh has no faces", "points"});
}

TEST(ImportSurfaceMesh, RefusesMeshOfLinesOnly) {
  ScratchDir dir;
  const std::string path = dir.Write("lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\n");
  ExpectRefused([&] { ImportSurfaceMesh(path, {}); }, {path, "mesh has no faces", "lines"});
}

TEST(ImportSurfaceMesh, RefusesLineAmongFaces) {
  ScratchDir dir;
  const std::string path = dir.Write("mixed.obj", std::string(kQuadObj) + "l 1 3\n");
  ExpectRefused([&] { ImportSurfaceMesh(path, {}); }, {path, "2 vertices"});
}

/// Counts the `v` and `f` lines of an OBJ file and the vertices of each face.
struct ObjCounts {
  int num_vertices = 0;
  int num_faces = 0;
  int num_quads = 0;
};

ObjCounts CountObjLines(const fs::path& path) {
  ObjCounts counts;
  std::ifstream stream(path);
  std::string line;
  while (std::getline(stream, line)) {
    std::istringstream words(line);
    std::string keyword, word;
    words >> keyword;
    if (keyword == "v") ++counts.num_vertices;
    if (keyword != "f") continue;
    ++counts.num_faces;
    int corners = 0;
    while (words >> word) ++corners;
    counts.num_quads += corners == 4 ? 1 : 0;
  }
  return counts;
}

TEST(ImportSurfaceMesh, ReadsMakeHumanGarmentIntoAClothOfDensityTimesArea) {
  const fs::path path = fs::path("..") / "shared" / "data" / "makehuman" / "clothes" /
                        "female_casualsuit01" / "female_casualsuit01.obj";
  if (!fs::exists(path)) GTEST_SKIP() << path << " is absent (the shared data folder)";
  // MakeHuman models are in decimetres (data/makehuman/SOURCE.md).
  MeshImportOptions options;
  options.scale = 0.1;
  const SurfaceMesh mesh = ImportSurfaceMesh(path.string(), options);
  const ObjCounts counts = CountObjLines(path);
  // Joining UV seams gives back the file's own vertex list (2,197 for this garment).
  EXPECT_EQ(mesh.vertices.rows(), counts.num_vertices);
  EXPECT_EQ(static_cast<int>(mesh.faces.size()), counts.num_faces);
  EXPECT_GT(counts.num_faces, 1000);
  int quads = 0;
  for (const auto& face : mesh.faces) quads += face.size() == 4 ? 1 : 0;
  EXPECT_EQ(quads, counts.num_quads);
  // About 1.7 m tall once in metres.
  const double height = mesh.vertices.col(1).maxCoeff() - mesh.vertices.col(1).minCoeff();
  EXPECT_GT(height, 1.0);
  EXPECT_LT(height, 2.0);

  const sim::Material material;
  const sim::ClothModelData data = sim::BuildMeshCloth(mesh, material, "casualsuit");
  double area = 0.0;
  for (const Eigen::Vector3i& t : data.triangles) {
    const Eigen::Vector3d a = data.rest_positions.row(t[0]).transpose();
    const Eigen::Vector3d b = data.rest_positions.row(t[1]).transpose();
    const Eigen::Vector3d c = data.rest_positions.row(t[2]).transpose();
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  EXPECT_EQ(data.triangles.size(),
            std::size_t(2 * counts.num_quads + (counts.num_faces - counts.num_quads)));
  EXPECT_GT(area, 0.5);  // a top and trousers: a couple of square metres
  EXPECT_LT(area, 4.0);
  EXPECT_NEAR(data.masses.sum(), material.density * area, 1e-12 * material.density * area);
  EXPECT_NO_THROW(sim::ClothModel::Create(data));
}

}  // namespace
}  // namespace costume::assets
