#include "assets/makehuman_import.h"

#include <gtest/gtest.h>

#include "assets/skeleton_families.h"
#include "sim_core/avatar/clip.h"
#include "sim_core/collision/mesh_distance.h"
#include "sim_core/common/input_error.h"
#include "tests/assets/import_test_support.h"

namespace costume::assets {
namespace {

using namespace costume::assets::testing;
using sim::HAnimJoint;
using sim::InputError;

const fs::path kBody = kData / "makehuman/body";

std::shared_ptr<const sim::Avatar> LoadBody() {
  return LoadMakeHumanAvatar((kBody / "base.obj").string(), (kBody / "default.mhskel").string(),
                             (kBody / "default_weights.mhw").string());
}

TEST(MakeHumanImport, BodyIsInMetresWithItsBones) {
  SKIP_WITHOUT("makehuman/body/default.mhskel");
  const auto avatar = LoadBody();
  // SOURCE.md: the body group has 13,380 vertices; the skeleton 163 bones.
  EXPECT_EQ(avatar->num_vertices(), 13380);
  EXPECT_EQ(avatar->skeleton().num_joints(), 163);
  const auto& v = avatar->rest_vertices();
  const double height = v.col(1).maxCoeff() - v.col(1).minCoeff();
  EXPECT_GT(height, 1.6);
  EXPECT_LT(height, 1.9);
  // Quads split in two: 13,378 quads → 26,756 triangles.
  EXPECT_EQ(avatar->triangles().size(), 2u * 13378u);
}

TEST(MakeHumanImport, WeightsAreValid) {
  SKIP_WITHOUT("makehuman/body/default.mhskel");
  const auto avatar = LoadBody();
  const auto& data = avatar->data();
  for (int i = 0; i < avatar->num_vertices(); ++i) {
    double sum = 0.0;
    for (int k = 0; k < sim::kMaxInfluences; ++k) {
      const int joint = data.influence_joints(i, k);
      const double weight = data.influence_weights(i, k);
      ASSERT_GE(weight, 0.0);
      if (joint < 0) {
        ASSERT_EQ(weight, 0.0);
        continue;
      }
      ASSERT_LT(joint, avatar->skeleton().num_joints());
      sum += weight;
    }
    ASSERT_NEAR(sum, 1.0, 1e-9) << "vertex " << i;
  }
}

TEST(MakeHumanImport, WeightsKeepTheObjVertexOrder) {
  SKIP_WITHOUT("makehuman/body/default.mhskel");
  // The vertices weighted mostly to the left foot must lie near the left foot joint:
  // a shuffled vertex order would scatter them over the body.
  const auto avatar = LoadBody();
  const sim::Skeleton& skeleton = avatar->skeleton();
  const int foot = skeleton.Find(HAnimJoint::kLTalocrural);
  ASSERT_GE(foot, 0);
  const Eigen::Vector3d ankle = skeleton.rest_world()[foot].translation();
  int count = 0;
  for (int i = 0; i < avatar->num_vertices(); ++i) {
    if (avatar->data().influence_joints(i, 0) != foot) continue;
    ++count;
    EXPECT_LT((avatar->rest_vertices().row(i).transpose() - ankle).norm(), 0.3) << "vertex " << i;
  }
  EXPECT_GT(count, 50);
}

TEST(MakeHumanImport, MappingCoversTheRetargetingMinimum) {
  SKIP_WITHOUT("makehuman/body/default.mhskel");
  const auto avatar = LoadBody();
  const sim::Skeleton& skeleton = avatar->skeleton();
  for (HAnimJoint joint : {HAnimJoint::kHumanoidRoot, HAnimJoint::kLHip, HAnimJoint::kRHip,
                           HAnimJoint::kLKnee, HAnimJoint::kRKnee, HAnimJoint::kLShoulder,
                           HAnimJoint::kRShoulder, HAnimJoint::kLElbow, HAnimJoint::kRElbow,
                           HAnimJoint::kLTalocrural, HAnimJoint::kRTalocrural,
                           HAnimJoint::kSkullbase}) {
    EXPECT_GE(skeleton.Find(joint), 0) << sim::HAnimName(joint);
  }
  EXPECT_NO_THROW(sim::Retargeter(avatar->shared_skeleton(), avatar->shared_skeleton()));
}

TEST(MakeHumanImport, JointsSitWhereTheAnatomySays) {
  SKIP_WITHOUT("makehuman/body/default.mhskel");
  const auto avatar = LoadBody();
  const sim::Skeleton& s = avatar->skeleton();
  const double floor = avatar->rest_vertices().col(1).minCoeff();
  // Knees at about a quarter to a third of the height, hips near half, the skull base
  // near the top; the character's left at +x (MakeHuman faces +z).
  EXPECT_NEAR(RestOf(s, HAnimJoint::kLKnee).y() - floor, 0.5, 0.1);
  EXPECT_NEAR(RestOf(s, HAnimJoint::kLHip).y() - floor, 0.9, 0.15);
  EXPECT_NEAR(RestOf(s, HAnimJoint::kSkullbase).y() - floor, 1.55, 0.15);
  EXPECT_GT(RestOf(s, HAnimJoint::kLHip).x(), RestOf(s, HAnimJoint::kRHip).x());
  EXPECT_GT(RestOf(s, HAnimJoint::kLShoulder).x(), RestOf(s, HAnimJoint::kRShoulder).x());
  EXPECT_GT(RestOf(s, HAnimJoint::kLElbow).x(), RestOf(s, HAnimJoint::kLShoulder).x());
}

TEST(MakeHumanImport, DamagedFilesThrowNamingTheFile) {
  SKIP_WITHOUT("makehuman/body/default.mhskel");
  ScratchDir dir;
  const std::string obj = (kBody / "base.obj").string();
  const std::string skel = (kBody / "default.mhskel").string();
  const std::string weights = (kBody / "default_weights.mhw").string();
  const std::string cut_skel = dir.WriteTruncated("cut.mhskel", skel);
  const std::string cut_weights = dir.WriteTruncated("cut.mhw", weights);
  const std::string junk_skel = dir.WriteGarbage("junk.mhskel", 5000);
  const std::string junk_obj = dir.WriteGarbage("junk.obj", 5000);
  const std::string cut_obj = dir.WriteTruncated("cut.obj", obj);
  struct Case {
    std::string obj, skel, weights, named;
  };
  for (const Case& c : {Case{obj, cut_skel, weights, "cut.mhskel"},
                        Case{obj, skel, cut_weights, "cut.mhw"},
                        Case{obj, junk_skel, weights, "junk.mhskel"},
                        Case{junk_obj, skel, weights, "junk.obj"},
                        Case{cut_obj, skel, weights, "cut"},
                        Case{obj, skel, dir.path().string() + "/missing.mhw", "missing.mhw"},
                        // A weight beyond 1: damaged (MakeHuman writes 0.001 to 1).
                        Case{obj, skel,
                             dir.Write("heavy.mhw", R"({"weights": {"root": [[0, 2147483648]]}})"),
                             "heavy.mhw: weights.root[0]: weight 2.14748e+09 (allowed: [0, 1])"}}) {
    try {
      LoadMakeHumanAvatar(c.obj, c.skel, c.weights);
      ADD_FAILURE() << "no error for " << c.named;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(c.named), std::string::npos) << e.what();
    }
  }
}

/// The fraction of `vertices` inside the body's skin.
double FractionInside(const sim::Points& vertices, const sim::Avatar& body) {
  const sim::MeshDistance skin("makehuman", body.rest_vertices(), body.triangles());
  int inside = 0;
  for (Eigen::Index v = 0; v < vertices.rows(); ++v) inside += skin.SignedDistance(vertices.row(v).transpose(), 0.2) < 0;
  return static_cast<double>(inside) / static_cast<double>(vertices.rows());
}

TEST(MakeHumanImport, GarmentsFitTheBodyByTheirMhclo) {
  SKIP_WITHOUT("makehuman/clothes/female_casualsuit02/female_casualsuit02.mhclo");
  const fs::path suit = kData / "makehuman/clothes/female_casualsuit02";
  const ObjMesh base = ReadObj((kBody / "base.obj").string());
  const sim::SurfaceMesh fitted = LoadMakeHumanGarment((suit / "female_casualsuit02.mhclo").string(), base);
  const ObjMesh authored = ReadObj((suit / "female_casualsuit02.obj").string());
  // SOURCE.md: 2,876 vertices, 2,744 quads, in the OBJ's order.
  ASSERT_EQ(fitted.vertices.rows(), 2876);
  EXPECT_EQ(fitted.faces, authored.faces);
  // The OBJ is the garment's authoring shape: 40 % of it lies inside base.obj's skin; fitted
  // over the helper surfaces, less than 15 % does (a tight suit, touching the skin).
  const auto body = LoadBody();
  EXPECT_GT(FractionInside(0.1 * authored.vertices, *body), 0.3);
  EXPECT_LT(FractionInside(fitted.vertices, *body), 0.15);
  // In metres, on the body: between the knees (shorts) and the shoulders.
  EXPECT_GT(fitted.vertices.col(1).minCoeff(), -0.5);
  EXPECT_LT(fitted.vertices.col(1).maxCoeff(), 0.7);
}

/// A scratch folder holding the suit's OBJ, which a .mhclo written there names.
void CopySuitObj(const ScratchDir& dir) {
  fs::copy_file(kData / "makehuman/clothes/female_casualsuit02/female_casualsuit02.obj",
                dir.path() / "female_casualsuit02.obj");
}

TEST(MakeHumanImport, DamagedMhcloThrowsNamingTheFile) {
  SKIP_WITHOUT("makehuman/clothes/female_casualsuit02/female_casualsuit02.mhclo");
  const fs::path suit = kData / "makehuman/clothes/female_casualsuit02";
  const ObjMesh base = ReadObj((kBody / "base.obj").string());
  ScratchDir dir;
  CopySuitObj(dir);
  for (const std::string& file :
       {dir.WriteTruncated("cut.mhclo", suit / "female_casualsuit02.mhclo"), dir.WriteGarbage("junk.mhclo", 4000),
        dir.Write("bad_row.mhclo", "obj_file female_casualsuit02.obj\nx_scale 5399 11998 1.3980\n"
                                   "z_scale 962 5320 1.8461\ny_scale 791 881 2.2048\nverts 0\n1 2 99999 0 0 1 0 0 0\n"),
        (dir.path() / "absent.mhclo").string()}) {
    try {
      LoadMakeHumanGarment(file, base);
      ADD_FAILURE() << "no error for " << file;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(fs::path(file).filename().string()), std::string::npos) << e.what();
    }
  }
}

// Found by mutating the real file: a weight of 1e308 gave the garment a vertex at infinity,
// which the loader returned.
TEST(MakeHumanImport, MhcloRowsOffTheBodyAreRefusedNamingTheLine) {
  SKIP_WITHOUT("makehuman/clothes/female_casualsuit02/female_casualsuit02.mhclo");
  const ObjMesh base = ReadObj((kBody / "base.obj").string());
  ScratchDir dir;
  CopySuitObj(dir);
  const std::string head =
      "obj_file female_casualsuit02.obj\nx_scale 5399 11998 1.3980\nz_scale 962 5320 1.8461\n"
      "y_scale 791 881 2.2048\nverts 0\n";
  const auto refusal = [&](const std::string& name, const std::string& row) {
    try {
      LoadMakeHumanGarment(dir.Write(name, head + row), base);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  // MakeHuman's weights need not lie in [0, 1] (its own reach -1.04 and 2.73), only sum to 1.
  EXPECT_NE(refusal("affine.mhclo", "1 2 3 2.5 -0.9 -0.6 0 0 0\n").find("vertex rows"),
            std::string::npos)
      << "an affine row passes the row checks and fails only on the count";
  EXPECT_NE(refusal("weight.mhclo", "1 2 3 1e308 0.1 0.2 0 0 0\n")
                .find("weight.mhclo:6: the weights"),
            std::string::npos);
  const std::string sum = refusal("sum.mhclo", "1 2 3 0.5 0.1 0.2 0 0 0\n");
  EXPECT_NE(sum.find("sum to 0.8 (allowed: 1 ± 0.001)"), std::string::npos) << sum;
  // Finite but far: an offset of 1e308, weights of ±5e4 that sum to 1, and an offset of 40
  // units (4 m; the body with its helpers is 16.9 units tall, its box's diagonal 20.1).
  for (const std::string row :
       {"1 2 3 0.5 0.3 0.2 1e308 0 0", "1 2 3 5e4 -5e4 1 0 0 0", "1 2 3 0.5 0.3 0.2 0 40 0"}) {
    const std::string far = refusal("far.mhclo", row + "\n");
    EXPECT_NE(far.find("far.mhclo:6: the row puts its vertex"), std::string::npos)
        << row << ": " << far;
  }
  EXPECT_NE(refusal("near.mhclo", "1 2 3 0.5 0.3 0.2 0 10 0\n").find("vertex rows"),
            std::string::npos)
      << "10 units (1 m) off is within the body's diagonal";
}

TEST(MakeHumanImport, ObjReaderKeepsOrderAndRefusesBadIndices) {
  ScratchDir dir;
  const ObjMesh mesh = ReadObj(dir.Write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\ng a\nf 1/1 2/2 3/3 -1\n"));
  ASSERT_EQ(mesh.vertices.rows(), 4);
  EXPECT_EQ(mesh.vertices(2, 0), 1.0);
  EXPECT_EQ(mesh.vertices(2, 1), 1.0);
  ASSERT_EQ(mesh.faces.size(), 1u);
  EXPECT_EQ(mesh.faces[0], (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(mesh.face_groups[0], "a");
  try {
    ReadObj(dir.Write("bad.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n"));
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.obj:3"), std::string::npos) << e.what();
  }
  // A byte flipped in a number (tools/fuzz_import.py) is named, not printed raw.
  try {
    ReadObj(dir.Write("flipped.obj", "v 0 0 0\nv 1.\xb4" "97 0 0\n"));
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("flipped.obj:2: '1.\\xb497' is not a finite number"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace costume::assets
