#include "assets/avatar_import.h"

#include <gtest/gtest.h>

#include <set>
#include <sstream>

#include "assets/skeleton_families.h"
#include "process/limited_child.h"
#include "sim_core/avatar/clip.h"
#include "sim_core/common/input_error.h"
#include "tests/assets/assimp_export_support.h"
#include "tests/assets/import_test_support.h"

namespace costume::assets {
namespace {

using namespace costume::assets::testing;
using sim::HAnimJoint;
using sim::InputError;

const fs::path kCesiumMan = kData / "khronos-cesiumman/CesiumMan.glb";

double Height(const sim::Avatar& avatar) {
  return avatar.rest_vertices().col(1).maxCoeff() - avatar.rest_vertices().col(1).minCoeff();
}

void ExpectValidWeights(const sim::Avatar& avatar) {
  const auto& data = avatar.data();
  for (int i = 0; i < avatar.num_vertices(); ++i) {
    double sum = 0.0;
    for (int k = 0; k < sim::kMaxInfluences; ++k) {
      ASSERT_GE(data.influence_weights(i, k), 0.0);
      if (data.influence_joints(i, k) >= 0) sum += data.influence_weights(i, k);
    }
    ASSERT_NEAR(sum, 1.0, 1e-9) << "vertex " << i;
  }
}

TEST(AvatarImport, CesiumManLoadsSkinnedInMetres) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  const auto avatar = LoadAvatar(kCesiumMan.string());
  // SOURCE.md: 19 joints, 2,612 vertices before joining seams, height ~1.5 m.
  EXPECT_EQ(avatar->skeleton().num_joints(), 19);
  EXPECT_GT(avatar->num_vertices(), 1500);
  EXPECT_LE(avatar->num_vertices(), 2612);
  EXPECT_EQ(avatar->triangles().size(), 4672u);
  EXPECT_NEAR(Height(*avatar), 1.5, 0.1);
  EXPECT_NEAR(avatar->rest_vertices().col(1).minCoeff(), 0.0, 0.05);  // feet on the floor
  ExpectValidWeights(*avatar);
  // Several joints do carry vertices.
  std::set<int> used;
  for (int i = 0; i < avatar->num_vertices(); ++i) used.insert(avatar->data().influence_joints(i, 0));
  EXPECT_GE(used.size(), 15u);
}

TEST(AvatarImport, CesiumManJointsMapOntoHAnim) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  const auto avatar = LoadAvatar(kCesiumMan.string());
  const sim::Skeleton& s = avatar->skeleton();
  for (HAnimJoint joint : {HAnimJoint::kHumanoidRoot, HAnimJoint::kLHip, HAnimJoint::kRHip,
                           HAnimJoint::kLKnee, HAnimJoint::kRKnee, HAnimJoint::kLShoulder,
                           HAnimJoint::kRShoulder, HAnimJoint::kLElbow, HAnimJoint::kRElbow}) {
    ASSERT_GE(s.Find(joint), 0) << sim::HAnimName(joint);
  }
  // Anatomy: knees between hips and ankles, elbows further out than shoulders.
  EXPECT_LT(RestOf(s, HAnimJoint::kLKnee).y(), RestOf(s, HAnimJoint::kLHip).y() - 0.15);
  EXPECT_LT(RestOf(s, HAnimJoint::kLTalocrural).y(), RestOf(s, HAnimJoint::kLKnee).y() - 0.15);
  EXPECT_GT(std::abs(RestOf(s, HAnimJoint::kLElbow).x()), std::abs(RestOf(s, HAnimJoint::kLShoulder).x()));
  // Left really is left: the toes (leg_joint_L_5, child of the ankle) point the way the
  // body faces, which is left-minus-right hip turned a quarter about +y.
  const int toe = s.FindByName("leg_joint_L_5");
  ASSERT_GE(toe, 0);
  Eigen::Vector3d left = RestOf(s, HAnimJoint::kLHip) - RestOf(s, HAnimJoint::kRHip);
  left.y() = 0;
  const Eigen::Vector3d forward = left.cross(Eigen::Vector3d::UnitY());
  EXPECT_GT((s.rest_world()[toe].translation() - RestOf(s, HAnimJoint::kLTalocrural)).dot(forward), 0.0);
  EXPECT_NO_THROW(sim::Retargeter(avatar->shared_skeleton(), avatar->shared_skeleton()));
}

TEST(AvatarImport, SkinningTheRestPoseGivesTheRestSurface) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  const auto avatar = LoadAvatar(kCesiumMan.string());
  std::vector<Eigen::Isometry3d> world, scratch;
  sim::ComputeJointWorld(avatar->skeleton(), sim::RestPose(avatar->skeleton()), world);
  sim::Points skinned;
  sim::SkinVertices(*avatar, world, scratch, skinned);
  EXPECT_LT((skinned - avatar->rest_vertices()).cwiseAbs().maxCoeff(), 1e-9);
}

/// The largest distance from a point of `points` to its nearest point of `reference` [m].
double FarthestFromNearest(const sim::Points& points, const sim::Points& reference) {
  double farthest = 0.0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const double nearest = (reference.rowwise() - points.row(i)).rowwise().squaredNorm().minCoeff();
    farthest = std::max(farthest, std::sqrt(nearest));
  }
  return farthest;
}

// The same body through assimp's FBX and Collada exporters (assimp_export_support.h): each
// file declares its own unit and up axis, so a wrong unit or axis detection shows as a
// height 100 times off or a body lying along z.
TEST(AvatarImport, CesiumManConvertedToFbxAndColladaMatchesTheGlb) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  const auto glb = LoadAvatar(kCesiumMan.string());
  const sim::Skeleton& expected = glb->skeleton();
  ScratchDir dir;
  for (Conversion conversion : kConversions) {
    SCOPED_TRACE(ConversionName(conversion));
    const fs::path file = dir.path() / ConvertedName(conversion);
    ExportCesiumMan(kCesiumMan, file, conversion);
    const auto avatar = LoadAvatar(file.string());
    // The exporters write every triangle corner as its own vertex; joined by position they
    // are the glTF's vertices again.
    EXPECT_EQ(avatar->num_vertices(), glb->num_vertices());
    EXPECT_EQ(avatar->triangles().size(), glb->triangles().size());
    EXPECT_NEAR(Height(*avatar), Height(*glb), 1e-4);
    EXPECT_LT(FarthestFromNearest(avatar->rest_vertices(), glb->rest_vertices()), 1e-4);
    ExpectValidWeights(*avatar);
    // Same joints, mapped onto the same H-Anim joints, at the same rest places.
    const sim::Skeleton& s = avatar->skeleton();
    ASSERT_EQ(s.num_joints(), expected.num_joints());
    for (int j = 0; j < expected.num_joints(); ++j) {
      const int same = s.FindByName(expected.joint(j).name);
      ASSERT_GE(same, 0) << expected.joint(j).name;
      EXPECT_EQ(s.joint(same).hanim, expected.joint(j).hanim) << expected.joint(j).name;
      EXPECT_LT((s.rest_world()[same].translation() - expected.rest_world()[j].translation()).norm(), 1e-4)
          << expected.joint(j).name;
    }
    std::vector<Eigen::Isometry3d> world, scratch;
    sim::ComputeJointWorld(s, sim::RestPose(s), world);
    sim::Points skinned;
    sim::SkinVertices(*avatar, world, scratch, skinned);
    EXPECT_LT((skinned - avatar->rest_vertices()).cwiseAbs().maxCoeff(), 1e-6);
  }
}

/// CesiumMan exported as COLLADA into `dir` (assimp_export_support.h).
fs::path ExportedCollada(const ScratchDir& dir) {
  const fs::path file = dir.path() / "man.dae";
  ExportCesiumMan(kCesiumMan, file, Conversion::kColladaCentimetres);
  return file;
}

// CesiumMan with its joints renamed as Rigify names the deform bones of a Blender rig: the
// importer finds the Blender family in the file and maps the same joints onto H-Anim.
TEST(AvatarImport, ARigNamedAsBlendersMapsAsTheOriginal) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  ScratchDir dir;
  const fs::path original = ExportedCollada(dir);
  std::string text = ReadBytes(original);
  // Longer names first: "Skeleton_arm_joint_R" begins two others.
  const std::pair<std::string, std::string> kRenames[] = {
      {"Skeleton_arm_joint_R__2_", "DEF-forearm.R"},
      {"Skeleton_arm_joint_R__3_", "DEF-hand.R"},
      {"Skeleton_arm_joint_R", "DEF-upper_arm.R"},
      {"Skeleton_arm_joint_L__4_", "DEF-upper_arm.L"},
      {"Skeleton_arm_joint_L__3_", "DEF-forearm.L"},
      {"Skeleton_arm_joint_L__2_", "DEF-hand.L"},
      {"Skeleton_torso_joint_1", "DEF-spine"},
      {"Skeleton_torso_joint_2", "DEF-spine.001"},
      {"Skeleton_neck_joint_1", "DEF-spine.004"},
      {"Skeleton_neck_joint_2", "DEF-spine.006"},
      {"leg_joint_L_1", "DEF-thigh.L"},
      {"leg_joint_L_2", "DEF-shin.L"},
      {"leg_joint_L_3", "DEF-foot.L"},
      {"leg_joint_R_1", "DEF-thigh.R"},
      {"leg_joint_R_2", "DEF-shin.R"},
      {"leg_joint_R_3", "DEF-foot.R"}};
  for (const auto& [from, to] : kRenames) {
    int replaced = 0;
    for (std::size_t at = text.find(from); at != std::string::npos;
         at = text.find(from, at + to.size())) {
      text.replace(at, from.size(), to);
      ++replaced;
    }
    EXPECT_GT(replaced, 0) << from;
  }
  const auto expected = LoadAvatar(original.string());
  const auto renamed = LoadAvatar(dir.Write("rigify.dae", text));
  for (sim::HAnimJoint joint : sim::AllHAnimJoints()) {
    const int e = expected->skeleton().Find(joint), r = renamed->skeleton().Find(joint);
    ASSERT_EQ(r < 0, e < 0) << sim::HAnimName(joint);
    if (e < 0) continue;
    EXPECT_EQ(renamed->skeleton().joint(r).name.substr(0, 4), "DEF-") << sim::HAnimName(joint);
    EXPECT_LT((renamed->skeleton().rest_world()[r].translation() -
               expected->skeleton().rest_world()[e].translation()).norm(), 1e-9)
        << sim::HAnimName(joint);
  }
}

// The built-in garments and the camera take an avatar to face +z (its left at +x), as
// glTF's own convention has it; a VRM 0.x faces −z. CesiumMan, which faces +z, turned in its
// file about the vertical (the export's z, its up axis) by a half and a quarter turn, is
// turned back at import: the same body in the same place.
TEST(AvatarImport, AnAvatarFacingAnotherWayIsTurnedToFacePlusZ) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  ScratchDir dir;
  const fs::path original = ExportedCollada(dir);
  const auto expected = LoadAvatar(original.string());
  const sim::Skeleton& skeleton = expected->skeleton();
  const auto hip = [](const sim::Skeleton& s, sim::HAnimJoint j) {
    return s.rest_world()[s.Find(j)].translation();
  };
  ASSERT_GT(hip(skeleton, sim::HAnimJoint::kLHip).x(), hip(skeleton, sim::HAnimJoint::kRHip).x());
  for (const char* degrees : {"180", "90", "-90"}) {
    SCOPED_TRACE(degrees);
    std::string turned = ReadBytes(original);
    const std::size_t scene = turned.find('>', turned.find("<visual_scene")) + 1;
    turned.insert(scene, std::string("<node id=\"turn\" name=\"turn\" type=\"NODE\">") +
                             "<rotate>0 0 1 " + degrees + "</rotate>");
    turned.insert(turned.find("</visual_scene>"), "</node>");
    const auto avatar = LoadAvatar(dir.Write("turned.dae", turned));
    ASSERT_EQ(avatar->num_vertices(), expected->num_vertices());
    EXPECT_LT((avatar->rest_vertices() - expected->rest_vertices()).cwiseAbs().maxCoeff(), 1e-5);
    for (sim::HAnimJoint joint : sim::AllHAnimJoints()) {
      if (skeleton.Find(joint) < 0) continue;
      EXPECT_LT((hip(avatar->skeleton(), joint) - hip(skeleton, joint)).norm(), 1e-5)
          << sim::HAnimName(joint);
    }
  }
}

TEST(AvatarImport, TruncatedConvertedFilesThrowNamingTheFile) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  ScratchDir dir;
  std::vector<std::string> files;
  for (Conversion conversion : kConversions) {
    const fs::path whole = dir.path() / ConvertedName(conversion);
    ExportCesiumMan(kCesiumMan, whole, conversion);
    files.push_back(dir.WriteTruncated("cut_" + ConvertedName(conversion), whole));
  }
  // As assimp 5.2.5 writes it, without the null records that close nested nodes.
  const fs::path unrepaired = dir.path() / "unrepaired.fbx";
  ExportCesiumMan(kCesiumMan, unrepaired, Conversion::kFbxBinaryCentimetres, false);
  files.push_back(unrepaired.string());
  for (const std::string& file : files) {
    try {
      LoadAvatar(file);
      ADD_FAILURE() << "no error for " << file;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
    }
  }
}

const char* kBoxObj =
    "v -20 0 -10\nv 20 0 -10\nv 20 0 10\nv -20 0 10\n"
    "v -20 170 -10\nv 20 170 -10\nv 20 170 10\nv -20 170 10\n"
    "f 1 2 3 4\nf 8 7 6 5\nf 1 5 6 2\nf 2 6 7 3\nf 3 7 8 4\nf 4 8 5 1\n";

TEST(AvatarImport, ObjIsAStaticAvatarOnOneRootJoint) {
  ScratchDir dir;
  AvatarImportOptions options;
  options.scale = 0.01;
  const auto avatar = LoadAvatar(dir.Write("box.obj", kBoxObj), options);
  ASSERT_EQ(avatar->skeleton().num_joints(), 1);
  EXPECT_EQ(avatar->skeleton().joint(0).hanim, HAnimJoint::kHumanoidRoot);
  EXPECT_EQ(avatar->num_vertices(), 8);
  EXPECT_EQ(avatar->triangles().size(), 12u);
  EXPECT_NEAR(Height(*avatar), 1.7, 1e-9);
  for (int i = 0; i < avatar->num_vertices(); ++i) {
    EXPECT_EQ(avatar->data().influence_joints(i, 0), 0);
    EXPECT_EQ(avatar->data().influence_weights(i, 0), 1.0);
  }
}

TEST(AvatarImport, UndeclaredUnitsAreGuessedFromTheHeight) {
  ScratchDir dir;
  // 170 units tall: centimetres.
  EXPECT_NEAR(Height(*LoadAvatar(dir.Write("box.obj", kBoxObj))), 1.7, 1e-9);
  // A declared z up: the 170 units along file y lie along −z afterwards.
  AvatarImportOptions options;
  options.scale = 0.01;
  options.up = UpAxis::kZ;
  const auto lying = LoadAvatar(dir.Write("box2.obj", kBoxObj), options);
  EXPECT_NEAR(Height(*lying), 0.2, 1e-9);
  EXPECT_NEAR(lying->rest_vertices().col(2).minCoeff(), -1.7, 1e-9);
}

// The check runs before assimp's JoinIdenticalVertices, which merges a vertex read as nan into
// another vertex (ImportSurfaceMesh returned a face folded onto itself, without a word).
TEST(AvatarImport, AVertexAtNoFinitePointIsRefusedNamingIt) {
  ScratchDir dir;
  std::string box = kBoxObj;
  box.replace(box.find("v 20 170 10"), 11, "v 20 nan 10");
  try {
    LoadAvatar(dir.Write("nan_box.obj", box));
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("nan_box.obj: mesh 0"), std::string::npos) << message;
    EXPECT_NE(message.find("(20, nan, 10) is not a finite point"), std::string::npos) << message;
  }
}

TEST(AvatarImport, DamagedFilesThrowNamingTheFile) {
  ScratchDir dir;
  std::vector<std::string> files = {dir.WriteGarbage("junk.glb", 4000), dir.WriteGarbage("junk.fbx", 4000),
                                    dir.WriteGarbage("junk.dae", 4000), dir.WriteGarbage("junk.obj", 4000),
                                    dir.Write("empty.obj", ""), (dir.path() / "absent.glb").string()};
  if (HaveData("khronos-cesiumman/CesiumMan.glb")) {
    files.push_back(dir.WriteTruncated("cut.glb", kCesiumMan));
  }
  for (const std::string& file : files) {
    try {
      LoadAvatar(file);
      ADD_FAILURE() << "no error for " << file;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(fs::path(file).filename().string()), std::string::npos)
          << e.what();
    }
  }
  AvatarImportOptions bad;
  bad.scale = -1;
  EXPECT_THROW(LoadAvatar(dir.Write("box.obj", kBoxObj), bad), InputError);
}

/// A glTF quad skinned to two joints (Hips, Spine; made by a script, not an exporter), with
/// its two inverse bind matrices given as the base64 text that ends its buffer.
std::string SkinnedQuad(const std::string& binds) {
  std::string text =
    "{\"asset\": {\"version\": \"2.0\"}, \"scene\": 0, \"scenes\": [{\"nodes\": [0, 2]}], \"nodes"
    "\": [{\"name\": \"Hips\", \"children\": [1]}, {\"name\": \"Spine\", \"translation\": [0, 1, "
    "0]}, {\"name\": \"mesh\", \"mesh\": 0, \"skin\": 0}], \"skins\": [{\"joints\": [0, 1], \"inv"
    "erseBindMatrices\": 4, \"skeleton\": 0}], \"meshes\": [{\"primitives\": [{\"attributes\": {"
    "\"POSITION\": 0, \"JOINTS_0\": 2, \"WEIGHTS_0\": 3}, \"indices\": 1}]}], \"buffers\": [{\"by"
    "teLength\": 284, \"uri\": \"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAA"
    "AAAAAAAAAAAAAgD8AAAAAAACAPwAAgD8AAAAAAAABAAIAAQADAAIAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA"
    "AAAAAAIA/AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAIA/AAAAAAAAAAAAAAAAAA@"
    "BINDS@AAAAAAAAAAAAAAAAAAAAAAAAgD8=\"}], \"bufferViews\": [{\"buffer\": 0, \"byteOffset\": 0,"
    " \"byteLength\": 48, \"target\": 34962}, {\"buffer\": 0, \"byteOffset\": 48, \"byteLength\":"
    " 12, \"target\": 34963}, {\"buffer\": 0, \"byteOffset\": 60, \"byteLength\": 32, \"target\":"
    " 34962}, {\"buffer\": 0, \"byteOffset\": 92, \"byteLength\": 64, \"target\": 34962}, {\"buff"
    "er\": 0, \"byteOffset\": 156, \"byteLength\": 128}], \"accessors\": [{\"bufferView\": 0, \"c"
    "omponentType\": 5126, \"count\": 4, \"type\": \"VEC3\", \"min\": [0, 0, 0], \"max\": [1, 1, "
    "0]}, {\"bufferView\": 1, \"componentType\": 5123, \"count\": 6, \"type\": \"SCALAR\"}, {\"bu"
    "fferView\": 2, \"componentType\": 5123, \"count\": 4, \"type\": \"VEC4\"}, {\"bufferView\": "
    "3, \"componentType\": 5126, \"count\": 4, \"type\": \"VEC4\"}, {\"bufferView\": 4, \"compone"
    "ntType\": 5126, \"count\": 2, \"type\": \"MAT4\"}]}";
  return text.replace(text.find("@BINDS@"), 7, binds);
}
/// Two identity matrices, and two of scale 0 (singular).
constexpr char kIdentityBinds[] =
    "CAPwAAAAAAAAAAAAAAAAAAAAAAAIA/AAAAAAAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAAAAAACAPwAAgD8AAA"
    "AAAAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAAAAAAIA/";
constexpr char kZeroBinds[] =
    "AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAACAPwAAAAAAAA"
    "AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA";

// A singular inverse bind matrix put every vertex of its bone in one place: the avatar was
// stored, invisible. The same quad with identity matrices loads.
TEST(AvatarImport, ASingularInverseBindMatrixIsRefusedNamingTheBone) {
  ScratchDir dir;
  EXPECT_EQ(LoadAvatar(dir.Write("quad.gltf", SkinnedQuad(kIdentityBinds)))->num_vertices(), 4);
  try {
    LoadAvatar(dir.Write("flat.gltf", SkinnedQuad(kZeroBinds)));
    ADD_FAILURE() << "a singular inverse bind matrix was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("flat.gltf: bone 'Hips'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("inverse bind matrix is singular"), std::string::npos)
        << e.what();
  }
}

/// `text` with the first occurrence of `from` replaced by `to`.
std::string Replaced(std::string text, const std::string& from, const std::string& to) {
  detail::ReplaceOnce(text, from, to);
  return text;
}

/// The same skeleton and skin weights; the rest vertices too unless `rest_vertices` is false.
void ExpectSameAvatar(const sim::Avatar& expected, const sim::Avatar& actual,
                      bool rest_vertices = true) {
  ASSERT_EQ(actual.num_vertices(), expected.num_vertices());
  if (rest_vertices) {
    EXPECT_EQ(actual.rest_vertices(), expected.rest_vertices());
  }
  EXPECT_EQ(actual.data().influence_joints, expected.data().influence_joints);
  EXPECT_EQ(actual.data().influence_weights, expected.data().influence_weights);
  ASSERT_EQ(actual.skeleton().num_joints(), expected.skeleton().num_joints());
  for (int j = 0; j < expected.skeleton().num_joints(); ++j) {
    EXPECT_TRUE(actual.skeleton().joint(j).rest_local.isApprox(
        expected.skeleton().joint(j).rest_local, 1e-12))
        << expected.skeleton().joint(j).name;
  }
}

// glTF lets a skin leave out its inverse bind matrices: each is then the identity. assimp
// 5.2 crashed on such a skin (SIGSEGV: it reads the absent accessor). Found by damaging a
// stored CesiumMan.glb: one flipped byte of "inverseBindMatrices" crashed `costume-catalog
// check`. The matrices are now written out before assimp reads the file, so the quad without
// them is the quad with identity matrices.
TEST(AvatarImport, ASkinWithoutInverseBindMatricesHasIdentityOnes) {
  ScratchDir dir;
  const std::string with = SkinnedQuad(kIdentityBinds);
  const std::string without = Replaced(with, "\"inverseBindMatrices\": 4, ", "");
  const auto expected = LoadAvatar(dir.Write("with.gltf", with));
  ExpectSameAvatar(*expected, *LoadAvatar(dir.Write("without.gltf", without)));
  // A GLB's JSON is amended in its chunk, the binary chunk after it kept: the stored GLB
  // whose damage found the crash reads its skeleton and weights as before (its rest vertices
  // move: identity matrices bind the mesh where its joints stand, not where it was bound).
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  const std::string flipped = Replaced(ReadBytes(kCesiumMan), "\"inverseBindMatrices\"",
                                       "\"xnverseBindMatrices\"");
  ExpectSameAvatar(*LoadAvatar(kCesiumMan.string()), *LoadAvatar(dir.Write("flipped.glb", flipped)),
                   /*rest_vertices=*/false);
}

// COLLADA lets a skin leave out its <bind_shape_matrix> (the identity); assimp 5.2 took a zero
// matrix instead, and the avatar was refused: every bone's inverse bind matrix singular. The
// exported CesiumMan's bind shape is the identity, so without it the body is the same.
TEST(AvatarImport, ACOLLADASkinWithoutBindShapeMatrixHasTheIdentity) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  ScratchDir dir;
  const fs::path with = ExportedCollada(dir);
  std::string without = ReadBytes(with);
  const std::string open = "<bind_shape_matrix>", close = "</bind_shape_matrix>";
  const std::size_t start = without.find(open), end = without.find(close);
  ASSERT_NE(start, std::string::npos);
  ASSERT_NE(end, std::string::npos);
  std::istringstream values(without.substr(start + open.size(), end - start - open.size()));
  for (int k = 0; k < 16; ++k) {
    double value = -1.0;
    values >> value;
    ASSERT_EQ(value, k % 5 == 0 ? 1.0 : 0.0) << "bind shape entry " << k;
  }
  without.erase(start, end + close.size() - start);
  ExpectSameAvatar(*LoadAvatar(with.string()), *LoadAvatar(dir.Write("without.dae", without)));
}

// A VRoid Studio avatar (.vrm) is a GLB with VRM's own extension in its JSON, which assimp
// reads only under the name .glb: it is handed over under that name. CesiumMan.glb as a .vrm
// stands in for one (no VRM file is at hand).
TEST(AvatarImport, AVrmIsReadAsTheGlbItIs) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  ScratchDir dir;
  ExpectSameAvatar(*LoadAvatar(kCesiumMan.string()),
                   *LoadAvatar(dir.Write("man.vrm", ReadBytes(kCesiumMan))));
}

// assimp reads as many matrices as the skin has joints, past the end of a shorter accessor.
TEST(AvatarImport, FewerInverseBindMatricesThanJointsAreRefusedNamingTheSkin) {
  ScratchDir dir;
  const std::string short_binds = Replaced(SkinnedQuad(kIdentityBinds),
                                           "\"count\": 2, \"type\": \"MAT4\"",
                                           "\"count\": 1, \"type\": \"MAT4\"");
  try {
    LoadAvatar(dir.Write("short.gltf", short_binds));
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "short.gltf: skin 0 has 1 inverse bind matrices for 2 joints (allowed: one per "
                  "joint)"),
              std::string::npos)
        << e.what();
  }
}

// A file that crashes assimp is refused, and this process goes on: a skin with no joints and
// no inverse bind matrices (glTF requires a joint) still crashes assimp 5.2 (SIGSEGV).
TEST(AvatarImport, AFileAssimpCrashesOnIsRefusedAndThisProcessGoesOn) {
  ScratchDir dir;
  const std::string no_joints = Replaced(SkinnedQuad(kIdentityBinds),
                                         "\"joints\": [0, 1], \"inverseBindMatrices\": 4",
                                         "\"joints\": []");
  const std::string path = dir.Write("no_joints.gltf", no_joints);
  try {
    LoadAvatar(path);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string message = e.what();
    // "crashed (signal 11, SIGSEGV)"; under AddressSanitizer, whose handler ends the child
    // with a report instead, "ended without a result".
    EXPECT_NE(message.find("no_joints.gltf: cannot read the avatar file: assimp "),
              std::string::npos)
        << message;
    EXPECT_NE(message.find("damaged or uses what this assimp cannot read"), std::string::npos)
        << message;
  }
  // Inside a limited child (the catalogue's import check) there is no second child: the crash
  // is that child's, which its caller reports.
  const process::ChildResult nested = process::RunLimited(
      [&] {
        LoadAvatar(path);
        return std::string();
      },
      {});
  EXPECT_EQ(nested.ending, process::ChildEnding::kCrashed);
  EXPECT_EQ(LoadAvatar(dir.Write("quad.gltf", SkinnedQuad(kIdentityBinds)))->num_vertices(), 4);
}

}  // namespace
}  // namespace costume::assets
