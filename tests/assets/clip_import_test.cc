#include "assets/clip_import.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "assets/makehuman_import.h"
#include "assets/skeleton_families.h"
#include "sim_core/common/input_error.h"
#include "tests/assets/assimp_export_support.h"
#include "tests/assets/import_test_support.h"

namespace costume::assets {
namespace {

using namespace costume::assets::testing;
using sim::HAnimJoint;
using sim::InputError;

std::string DataPath(const std::string& relative) { return (kData / relative).string(); }

/// A two-joint BVH: root at the origin with the given rotation channels and values, one
/// child 10 units up. With scale 0.01, the child is 0.1 m from the root.
std::string TwoJointBvh(const std::string& channels, const std::string& values) {
  return "HIERARCHY\nROOT a\n{\n  OFFSET 0 0 0\n  CHANNELS 5 Xposition Yposition Zposition " + channels +
         "\n  JOINT b\n  {\n    OFFSET 0 10 0\n    CHANNELS 0\n    End Site\n    {\n      OFFSET 0 5 0\n"
         "    }\n  }\n}\nMOTION\nFrames: 1\nFrame Time: 0.5\n0 0 0 " + values + "\n";
}

Eigen::Vector3d ChildOffset(const sim::Clip& clip) {
  std::vector<Eigen::Isometry3d> world;
  sim::ComputeJointWorld(*clip.skeleton, clip.frames[0], world);
  return world[1].translation() - world[0].translation();
}

TEST(BvhImport, RotationChannelsApplyInTheOrderListed) {
  ScratchDir dir;
  ClipImportOptions options;
  options.scale = 0.01;
  options.up = UpAxis::kY;
  // Rx(90)·Rz(90)·(0, 1, 0) = Rx(90)·(−1, 0, 0) = (−1, 0, 0);
  // Rz(90)·Rx(90)·(0, 1, 0) = Rz(90)·(0, 0, 1) = (0, 0, 1).
  const sim::Clip xz = LoadClip(dir.Write("xz.bvh", TwoJointBvh("Xrotation Zrotation", "90 90")), options);
  const sim::Clip zx = LoadClip(dir.Write("zx.bvh", TwoJointBvh("Zrotation Xrotation", "90 90")), options);
  EXPECT_TRUE(ChildOffset(xz).isApprox(Eigen::Vector3d(-0.1, 0, 0), 1e-9)) << ChildOffset(xz).transpose();
  EXPECT_TRUE(ChildOffset(zx).isApprox(Eigen::Vector3d(0, 0, 0.1), 1e-9)) << ChildOffset(zx).transpose();
  EXPECT_EQ(xz.frame_time, 0.5);
}

TEST(BvhImport, ZUpFilesBecomeYUp) {
  ScratchDir dir;
  ClipImportOptions options;
  options.scale = 0.01;
  options.up = UpAxis::kZ;
  // No rotation: the child is 10 units along file +y, which is −z after the turn.
  const sim::Clip clip = LoadClip(dir.Write("z.bvh", TwoJointBvh("Xrotation Zrotation", "0 0")), options);
  EXPECT_TRUE(ChildOffset(clip).isApprox(Eigen::Vector3d(0, 0, -0.1), 1e-9)) << ChildOffset(clip).transpose();
  // A file rotation about its z (up) axis is a rotation about y after the turn:
  // Rz(90)·(0, 10, 0) = (−10, 0, 0) in the file, (−0.1, 0, 0) in y-up metres.
  const sim::Clip turned = LoadClip(dir.Write("t.bvh", TwoJointBvh("Xrotation Zrotation", "0 90")), options);
  EXPECT_TRUE(ChildOffset(turned).isApprox(Eigen::Vector3d(-0.1, 0, 0), 1e-9)) << ChildOffset(turned).transpose();
}

TEST(BvhImport, RootStandsOnTheFloorAndMovesByItsPositionChannels) {
  ScratchDir dir;
  ClipImportOptions options;
  options.scale = 0.01;
  options.up = UpAxis::kY;
  options.start_at_origin = false;
  // A hanging chain: root, child 10 below, end 5 below that: the rest root stands 0.15 m up.
  const std::string text =
      "HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
      " JOINT b\n {\n  OFFSET 0 -10 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 -5 0\n  }\n }\n}\n"
      "MOTION\nFrames: 2\nFrame Time: 0.1\n1 15 2 0 0 0 0 0 0\n3 15 2 0 0 0 0 0 0\n";
  const sim::Clip clip = LoadClip(dir.Write("walk.bvh", text), options);
  EXPECT_NEAR(clip.skeleton->rest_world()[0].translation().y(), 0.15, 1e-12);
  EXPECT_TRUE(clip.frames[0].root_translation.isApprox(Eigen::Vector3d(0.01, 0.0, 0.02), 1e-12));
  EXPECT_TRUE(clip.frames[1].root_translation.isApprox(Eigen::Vector3d(0.03, 0.0, 0.02), 1e-12));
  options.start_at_origin = true;
  const sim::Clip moved = LoadClip(dir.Write("walk2.bvh", text), options);
  EXPECT_TRUE(moved.frames[1].root_translation.isApprox(Eigen::Vector3d(0.02, 0.0, 0.0), 1e-12));
}

TEST(BvhImport, MalformedTextNamesFileAndLine) {
  ScratchDir dir;
  const std::string good = TwoJointBvh("Xrotation Zrotation", "1 2");
  struct Case {
    std::string text, expected;
  };
  for (const Case& c :
       {Case{"HIERARCHY\nROOT a\n{\n OFFSET 0 x 0\n", "bad.bvh:4"},
        Case{"HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 2 Xrotation Wrotation\n", "Wrotation"},
        Case{good.substr(0, good.size() - 4), "ends in frame 0 of 1"},
        Case{good + "7\n", "does not match"},
        Case{"HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 9\n", "0..6"},
        Case{"MOTION\n", "expected 'HIERARCHY'"},
        Case{"HIERARCHY\nROOT a\n{\n OFFSET 0 \x10" "1 0\n", "OFFSET value is '\\x101'"}}) {
    try {
      LoadClip(dir.Write("bad.bvh", c.text));
      ADD_FAILURE() << "no error for: " << c.text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.bvh"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
    }
  }
  try {
    LoadClip(dir.Write("time.bvh", TwoJointBvh("Xrotation Zrotation", "1 2").replace(
                                        good.find("0.5"), 3, "-1.")));
    ADD_FAILURE();
  } catch (const InputError& e) {
    // Placed on the Frame Time line (18), not the first frame's after it.
    EXPECT_NE(std::string(e.what()).find("time.bvh:18: Frame Time is -1 s (allowed: [0.0001, 10])"),
              std::string::npos)
        << e.what();
  }
  // A whole clip in no time: 1e-300 s a frame used to be taken and played as one pose.
  try {
    LoadClip(dir.Write("instant.bvh", TwoJointBvh("Xrotation Zrotation", "1 2").replace(
                                          good.find("0.5"), 3, "1e-300")));
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("instant.bvh:18: Frame Time is 1e-300 s"), std::string::npos)
        << e.what();
  }
  // A rotation of -1e308 degrees (tools/fuzz_import.py stored one) turned the joint to an
  // arbitrary angle; 1e5 degrees, 278 turns, is the most a channel may hold.
  const std::string turns = dir.Write("turns.bvh", TwoJointBvh("Xrotation Zrotation", "1 -1e5"));
  EXPECT_EQ(LoadClip(turns).frames.size(), 1u);
  try {
    LoadClip(dir.Write("spun.bvh", TwoJointBvh("Xrotation Zrotation", "1 -1e308")));
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("spun.bvh:19: frame 0, joint 'a' Zrotation = -1e+308 "
                                         "degrees (allowed: within ±100000)"),
              std::string::npos)
        << e.what();
  }
}

struct RealClip {
  const char* file;
  int frames;
  double frame_time;
};

TEST(ClipImport, RealBvhFilesMatchTheirHeaders) {
  SKIP_WITHOUT("cmu-mocap-bvh/02_02.bvh");
  SKIP_WITHOUT("makehuman/bvh/walk1_mhskel.bvh");
  // Frames and Frame Time as the files' headers state them.
  for (const RealClip& c : {RealClip{"cmu-mocap-bvh/02_02.bvh", 299, 0.00833333},
                            RealClip{"cmu-mocap-bvh/10_01.bvh", 201, 0.0333333},
                            RealClip{"makehuman/bvh/walk1_mhskel.bvh", 14, 0.0416667}}) {
    const sim::Clip clip = LoadClip(DataPath(c.file));
    EXPECT_EQ(static_cast<int>(clip.frames.size()), c.frames) << c.file;
    EXPECT_NEAR(clip.frame_time, c.frame_time, 1e-6) << c.file;
    // A standing adult: 1.3–2.0 m from the toes to the top joint of the head.
    EXPECT_GT(RestHeight(*clip.skeleton), 1.3) << c.file;
    EXPECT_LT(RestHeight(*clip.skeleton), 2.0) << c.file;
    // The head is above the hips: y is up.
    EXPECT_GT(RestOf(*clip.skeleton, HAnimJoint::kSkullbase).y(),
              RestOf(*clip.skeleton, HAnimJoint::kHumanoidRoot).y() + 0.4) << c.file;
  }
}

TEST(ClipImport, DeepMimicClipsLoad) {
  SKIP_WITHOUT("deepmimic-motions/motions/humanoid3d_walk.txt");
  // SOURCE.md: frames and dt; a "wrap" clip drops its last frame (a copy of the first pose).
  struct Case {
    const char* name;
    int file_frames;
    double dt;
    bool loops;
  };
  for (const Case& c : {Case{"walk", 39, 1 / 30.0, true}, Case{"run", 25, 1 / 30.0, true},
                        Case{"jump", 107, 1 / 60.0, true}, Case{"kick", 47, 1 / 30.0, false},
                        Case{"dance_a", 98, 1 / 60.0, true}}) {
    const sim::Clip clip =
        LoadClip(DataPath(std::string("deepmimic-motions/motions/humanoid3d_") + c.name + ".txt"));
    EXPECT_EQ(static_cast<int>(clip.frames.size()), c.loops ? c.file_frames - 1 : c.file_frames) << c.name;
    EXPECT_NEAR(clip.frame_time, c.dt, 1e-4) << c.name;
    EXPECT_EQ(clip.loops, c.loops) << c.name;
    EXPECT_EQ(clip.skeleton->num_joints(), 15);
  }
}

TEST(ClipImport, CesiumManWalkIsTwoSeconds) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  const sim::Clip clip = LoadClip(DataPath("khronos-cesiumman/CesiumMan.glb"));
  EXPECT_NEAR(clip.duration(), 2.0, 0.05);
  EXPECT_EQ(clip.skeleton->num_joints(), 19);
  EXPECT_TRUE(clip.loops);
}

/// Each frame's world positions of the root and both ankles [m].
std::vector<std::array<Eigen::Vector3d, 3>> RootAndAnkles(const sim::Clip& clip) {
  const sim::Skeleton& s = *clip.skeleton;
  const int joints[3] = {s.Find(HAnimJoint::kHumanoidRoot), s.Find(HAnimJoint::kLTalocrural),
                         s.Find(HAnimJoint::kRTalocrural)};
  std::vector<std::array<Eigen::Vector3d, 3>> track;
  std::vector<Eigen::Isometry3d> world;
  for (const sim::Pose& frame : clip.frames) {
    sim::ComputeJointWorld(s, frame, world);
    track.push_back({world[joints[0]].translation(), world[joints[1]].translation(),
                     world[joints[2]].translation()});
  }
  return track;
}

// The walk through assimp's FBX and Collada exporters (assimp_export_support.h, which puts
// the animation in seconds first: assimp 5.2.5 writes ticks where seconds are due).
TEST(ClipImport, CesiumManWalkConvertedToFbxAndColladaMatchesTheGlb) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  const fs::path glb_path = kData / "khronos-cesiumman/CesiumMan.glb";
  // Sampled at the walk's own key times (48 keys over 2 s): between keys FBX interpolates
  // Euler angles, and the exporter writes them wrapped at ±180° (a turn of almost 360°
  // between two keys, which assimp's reader honours: up to 0.8 m off at 30 Hz).
  ClipImportOptions at_keys;
  at_keys.sample_rate = 24.0;
  const sim::Clip glb = LoadClip(glb_path.string(), at_keys);
  const auto expected = RootAndAnkles(glb);
  ScratchDir dir;
  for (Conversion conversion : kConversions) {
    SCOPED_TRACE(ConversionName(conversion));
    const fs::path file = dir.path() / ConvertedName(conversion);
    ExportCesiumMan(glb_path, file, conversion);
    EXPECT_NEAR(LoadClip(file.string()).duration(), 2.0, 0.05);
    const sim::Clip clip = LoadClip(file.string(), at_keys);
    EXPECT_EQ(clip.frames.size(), glb.frames.size());
    EXPECT_NEAR(clip.frame_time, glb.frame_time, 1e-9);
    EXPECT_EQ(clip.loops, glb.loops);
    ASSERT_EQ(clip.skeleton->num_joints(), glb.skeleton->num_joints());
    // The hips and feet move as in the glTF, frame by frame, within 1 mm.
    const auto track = RootAndAnkles(clip);
    ASSERT_EQ(track.size(), expected.size());
    double worst = 0.0;
    for (std::size_t f = 0; f < track.size(); ++f) {
      for (int k = 0; k < 3; ++k) worst = std::max(worst, (track[f][k] - expected[f][k]).norm());
    }
    EXPECT_LT(worst, 1e-3);
  }
  // The oracle is not trivial: the glTF's ankles move by decimetres over the walk.
  double swing = 0.0;
  for (const auto& frame : expected) swing = std::max(swing, (frame[1] - expected[0][1]).norm());
  EXPECT_GT(swing, 0.1);
}

std::string Base64(const std::string& bytes) {
  static const char kDigits[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string text;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::size_t left = std::min<std::size_t>(3, bytes.size() - i);
    unsigned word = 0;
    for (std::size_t k = 0; k < 3; ++k) {
      word = word << 8 | (k < left ? static_cast<unsigned char>(bytes[i + k]) : 0u);
    }
    for (std::size_t d = 0; d < 4; ++d) {
      text += d <= left ? kDigits[(word >> (18 - 6 * d)) & 63] : '=';  // '=' pads the last
    }
  }
  return text;
}

/// A glTF of two nodes (Hips and its child Spine, 10 cm up) whose one animation turns Spine
/// through `xyzw` (glTF's order) at `times` [s]; made here, not by an exporter.
std::string RotationKeysGltf(const std::vector<float>& times,
                             const std::vector<std::array<float, 4>>& xyzw) {
  std::string bytes;
  const auto put = [&](float v) { bytes.append(reinterpret_cast<const char*>(&v), sizeof v); };
  for (float t : times) put(t);
  const std::size_t quats_at = bytes.size();
  for (const auto& q : xyzw) for (float v : q) put(v);
  const auto n = std::to_string(times.size());
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"name": "Hips", "children": [1]}, {"name": "Spine", "translation": [0, 0.1, 0]}],
  "buffers": [{"byteLength": )" + std::to_string(bytes.size()) +
         R"(, "uri": "data:application/octet-stream;base64,)" + Base64(bytes) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": )" +
         std::to_string(quats_at) + R"(},
                  {"buffer": 0, "byteOffset": )" + std::to_string(quats_at) +
         R"(, "byteLength": )" + std::to_string(bytes.size() - quats_at) + R"(}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": )" + n +
         R"(, "type": "SCALAR", "min": [0], "max": [1]},
                {"bufferView": 1, "componentType": 5126, "count": )" + n +
         R"(, "type": "VEC4"}],
  "animations": [{"samplers": [{"input": 0, "output": 1, "interpolation": "LINEAR"}],
                  "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}]}]})";
}

// Keys sampling cannot use were dropped without a word: a zero or NaN quaternion became the
// rest rotation, NaN or decreasing times left one frame. The same file with good keys loads,
// turning Spine a quarter about z by its end (the glTF's own keys).
TEST(ClipImport, GltfKeysThatAreNoRotationOrGoBackInTimeAreRefused) {
  ScratchDir dir;
  const float h = std::sqrt(0.5f);
  const sim::Clip good = LoadClip(
      dir.Write("good.gltf", RotationKeysGltf({0, 1}, {{0, 0, 0, 1}, {0, 0, h, h}})));
  // The skeleton holds the nodes the animation moves: Spine alone.
  ASSERT_EQ(good.skeleton->num_joints(), 1);
  ASSERT_EQ(good.skeleton->joint(0).name, "Spine");
  const Eigen::AngleAxisd last(good.frames.back().rotations[0]);
  EXPECT_NEAR(last.angle() * last.axis().z(), std::acos(-1.0) / 2, 1e-6);
  struct Case {
    std::vector<float> times;
    std::vector<std::array<float, 4>> xyzw;
    std::string expected;
  };
  for (const Case& c : {Case{{0, 1}, {{0, 0, 0, 0}, {0, 0, 0, 1}},
                             "bad.gltf: node 'Spine' rotation key 0: (w, x, y, z) = (0, 0, 0, 0) "
                             "is not a rotation"},
                        Case{{0, 1}, {{0, 0, 0, 1}, {NAN, 0, 0, 1}},
                             "rotation key 1: (w, x, y, z) = (1, nan, 0, 0)"},
                        Case{{1, 0}, {{0, 0, 0, 1}, {0, 0, 0, 1}},
                             "rotation key 1: time 0 ticks (allowed: finite, not before"}}) {
    try {
      LoadClip(dir.Write("bad.gltf", RotationKeysGltf(c.times, c.xyzw)));
      ADD_FAILURE() << "accepted: " << c.expected;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
    }
  }
}

TEST(ClipImport, TruncatedConvertedFilesThrowNamingTheFile) {
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  ScratchDir dir;
  for (Conversion conversion : kConversions) {
    const fs::path whole = dir.path() / ConvertedName(conversion);
    ExportCesiumMan(kData / "khronos-cesiumman/CesiumMan.glb", whole, conversion);
    const std::string cut = dir.WriteTruncated("cut_" + ConvertedName(conversion), whole);
    try {
      LoadClip(cut);
      ADD_FAILURE() << "no error for " << cut;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(cut), std::string::npos) << e.what();
    }
  }
}

/// Peak-to-peak, over the clip retargeted onto the MakeHuman skeleton, of each ankle's
/// position relative to the hips along the body's facing direction [m]; also the least
/// height of the hips above the ankles.
struct Swing {
  double left = 0, right = 0, least_leg_height = 1e9, greatest_leg_height = -1e9;
};

Swing MeasureSwing(const sim::Clip& clip, const std::shared_ptr<const sim::Skeleton>& target) {
  const sim::Retargeter retargeter(clip.skeleton, target);
  const int root = target->Find(HAnimJoint::kHumanoidRoot);
  const int l_hip = target->Find(HAnimJoint::kLHip), r_hip = target->Find(HAnimJoint::kRHip);
  const int l_ankle = target->Find(HAnimJoint::kLTalocrural);
  const int r_ankle = target->Find(HAnimJoint::kRTalocrural);
  double l_lo = 1e9, l_hi = -1e9, r_lo = 1e9, r_hi = -1e9;
  Swing swing;
  sim::Pose pose;
  std::vector<Eigen::Isometry3d> world;
  for (const sim::Pose& frame : clip.frames) {
    retargeter.Apply(frame, pose);
    sim::ComputeJointWorld(*target, pose, world);
    // The body's own forward: left minus right hip, turned a quarter about +y.
    Eigen::Vector3d left = world[l_hip].translation() - world[r_hip].translation();
    left.y() = 0;
    const Eigen::Vector3d forward = left.cross(Eigen::Vector3d::UnitY()).normalized();
    const Eigen::Vector3d hips = world[root].translation();
    const double l = (world[l_ankle].translation() - hips).dot(forward);
    const double r = (world[r_ankle].translation() - hips).dot(forward);
    l_lo = std::min(l_lo, l), l_hi = std::max(l_hi, l);
    r_lo = std::min(r_lo, r), r_hi = std::max(r_hi, r);
    const double l_height = hips.y() - world[l_ankle].translation().y();
    const double r_height = hips.y() - world[r_ankle].translation().y();
    swing.least_leg_height = std::min({swing.least_leg_height, l_height, r_height});
    swing.greatest_leg_height = std::max({swing.greatest_leg_height, l_height, r_height});
  }
  swing.left = l_hi - l_lo;
  swing.right = r_hi - r_lo;
  return swing;
}

std::shared_ptr<const sim::Skeleton> MakeHumanSkeleton() {
  const std::string body = DataPath("makehuman/body/");
  return LoadMakeHumanSkeleton(body + "default.mhskel", ReadObj(body + "base.obj"), 0.1);
}

TEST(ClipImport, WalksRetargetedOntoMakeHumanSwingTheFeet) {
  SKIP_WITHOUT("makehuman/body/default.mhskel");
  SKIP_WITHOUT("cmu-mocap-bvh/02_02.bvh");
  SKIP_WITHOUT("deepmimic-motions/motions/humanoid3d_walk.txt");
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  const auto target = MakeHumanSkeleton();
  for (const char* file : {"cmu-mocap-bvh/02_02.bvh", "makehuman/bvh/walk1_mhskel.bvh",
                           "deepmimic-motions/motions/humanoid3d_walk.txt",
                           "khronos-cesiumman/CesiumMan.glb"}) {
    const Swing swing = MeasureSwing(LoadClip(DataPath(file)), target);
    // A walking stride swings each foot 0.2–1.1 m fore and aft of the hips on MakeHuman's
    // 0.8 m legs (CesiumMan's stylised walk is the longest: 0.6 m on its own 0.53 m legs);
    // the feet stay below the hips, the stance leg nearly straight, the swing leg bent
    // (a wrong up axis or unit fails one or the other).
    EXPECT_GT(swing.left, 0.2) << file;
    EXPECT_LT(swing.left, 1.1) << file;
    EXPECT_GT(swing.right, 0.2) << file;
    EXPECT_LT(swing.right, 1.1) << file;
    EXPECT_GT(swing.least_leg_height, 0.3) << file;
    EXPECT_GT(swing.greatest_leg_height, 0.7) << file;
    EXPECT_LT(swing.greatest_leg_height, 0.9) << file;
  }
}

TEST(ClipImport, KicksRetargetOntoMakeHuman) {
  SKIP_WITHOUT("makehuman/body/default.mhskel");
  SKIP_WITHOUT("cmu-mocap-bvh/10_01.bvh");
  SKIP_WITHOUT("deepmimic-motions/motions/humanoid3d_kick.txt");
  const auto target = MakeHumanSkeleton();
  for (const char* file : {"cmu-mocap-bvh/10_01.bvh", "deepmimic-motions/motions/humanoid3d_kick.txt"}) {
    const Swing swing = MeasureSwing(LoadClip(DataPath(file)), target);
    // A kick throws one foot well forward of the hips: a bigger swing than walking's least.
    EXPECT_GT(std::max(swing.left, swing.right), 0.4) << file;
    EXPECT_LT(std::max(swing.left, swing.right), 2.0) << file;
  }
}

TEST(ClipImport, DamagedFilesThrowNamingTheFile) {
  SKIP_WITHOUT("cmu-mocap-bvh/02_02.bvh");
  SKIP_WITHOUT("deepmimic-motions/motions/humanoid3d_walk.txt");
  SKIP_WITHOUT("khronos-cesiumman/CesiumMan.glb");
  ScratchDir dir;
  fs::create_directories(dir.path() / "motions");
  fs::create_directories(dir.path() / "characters");
  fs::copy_file(kData / "deepmimic-motions/characters/humanoid3d.txt",
                dir.path() / "characters/humanoid3d.txt");
  std::vector<std::string> files = {
      dir.WriteTruncated("cut.bvh", kData / "cmu-mocap-bvh/02_02.bvh"),
      dir.WriteGarbage("junk.bvh", 4000),
      dir.WriteTruncated("motions/cut_walk.txt", kData / "deepmimic-motions/motions/humanoid3d_walk.txt"),
      dir.WriteGarbage("motions/junk_walk.txt", 4000),
      dir.WriteTruncated("cut_man.glb", kData / "khronos-cesiumman/CesiumMan.glb"),
      dir.WriteGarbage("junk_man.glb", 4000),
      dir.WriteGarbage("junk_man.fbx", 4000),
      dir.WriteGarbage("junk_man.dae", 4000),
      (dir.path() / "absent.bvh").string()};
  // A damaged character file under a good motion.
  dir.WriteTruncated("characters/humanoid3d.txt.cut", kData / "deepmimic-motions/characters/humanoid3d.txt");
  for (const std::string& file : files) {
    try {
      LoadClip(file);
      ADD_FAILURE() << "no error for " << file;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(fs::path(file).filename().string()), std::string::npos)
          << e.what();
    }
  }
  ClipImportOptions options;
  options.deepmimic_character = (dir.path() / "characters/humanoid3d.txt.cut").string();
  try {
    LoadClip(DataPath("deepmimic-motions/motions/humanoid3d_walk.txt"), options);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("humanoid3d.txt.cut"), std::string::npos) << e.what();
  }
}

TEST(SkeletonFamilies, DetectsEachFamilyFromRealNames) {
  EXPECT_EQ(DetectFamily({"hip", "abdomen", "chest", "neck", "head", "lShldr", "lForeArm", "lHand", "rShldr",
                          "rForeArm", "rHand", "lThigh", "lShin", "lFoot", "rThigh", "rShin", "rFoot"}),
            SkeletonFamily::kPoserBvh);
  EXPECT_EQ(DetectFamily({"mixamorig:Hips", "mixamorig:Spine", "mixamorig:LeftUpLeg", "mixamorig:LeftLeg",
                          "mixamorig:RightUpLeg", "mixamorig:RightLeg", "mixamorig:LeftArm",
                          "mixamorig:LeftForeArm", "mixamorig:RightArm", "mixamorig:RightForeArm"}),
            SkeletonFamily::kMixamo);
  EXPECT_EQ(DetectFamily({"HumanoidRoot", "l_hip", "r_hip", "l_knee", "r_knee", "l_shoulder", "r_shoulder",
                          "l_elbow", "r_elbow"}),
            SkeletonFamily::kHAnim);
  EXPECT_EQ(DetectFamily({"a", "b", "Hips"}), SkeletonFamily::kUnknown);
  // The same name means different joints in different families.
  EXPECT_EQ(LookUpJoint(SkeletonFamily::kBiovisionBvh, "LeftShoulder"), HAnimJoint::kLShoulder);
  EXPECT_EQ(LookUpJoint(SkeletonFamily::kCmuCgspeed, "LeftShoulder"), std::nullopt);
  EXPECT_EQ(LookUpJoint(SkeletonFamily::kMixamo, "mixamorig1:LeftArm"), HAnimJoint::kLShoulder);
}

/// The name of the joint each H-Anim id lands on when `family` maps joints named `names`,
/// and (in `count`) the number mapped.
std::map<HAnimJoint, std::string> Mapped(SkeletonFamily family,
                                         const std::vector<std::string>& names, int& count) {
  std::vector<sim::Joint> joints(names.size());
  for (std::size_t j = 0; j < names.size(); ++j) joints[j].name = names[j];
  count = ApplyFamily(family, joints);
  std::map<HAnimJoint, std::string> mapped;
  for (const sim::Joint& joint : joints) {
    if (joint.hanim) mapped[*joint.hanim] = joint.name;
  }
  return mapped;
}

/// Both sides of each name holding `{side}`, with `left` and `right` put in its place.
std::vector<std::string> Sided(const std::vector<std::string>& names, const std::string& left,
                               const std::string& right) {
  std::vector<std::string> all;
  for (const std::string& name : names) {
    const std::size_t at = name.find("{side}");
    if (at == std::string::npos) {
      all.push_back(name);
      continue;
    }
    for (const std::string& side : {left, right}) {
      all.push_back(std::string(name).replace(at, 6, side));
    }
  }
  return all;
}

/// An Unreal-style rig (root on the floor, the pelvis 1 m above it, spine, arms, legs: made
/// by a script) whose one animation raises the pelvis 10 cm in 1 s and leaves the root still;
/// its skin (one triangle on the pelvis) has no inverse bind matrices.
constexpr char kPelvisRisingClip[] =
    R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0,17]}],"nodes":[{"name":"root")"
    R"(,"translation":[0,0,0],"children":[1]},{"name":"pelvis","translation":[0,1,0],"children")"
    R"(:[2,11,14]},{"name":"spine_01","translation":[0,0.1,0],"children":[3,5,8]},{"name":"neck)"
    R"(_01","translation":[0,0.4,0],"children":[4]},{"name":"head","translation":[0,0.1,0]},{"n)"
    R"(ame":"upperarm_l","translation":[0.2,0.35,0],"children":[6]},{"name":"lowerarm_l","trans)"
    R"(lation":[0.3,0,0],"children":[7]},{"name":"hand_l","translation":[0.25,0,0]},{"name":"up)"
    R"(perarm_r","translation":[-0.2,0.35,0],"children":[9]},{"name":"lowerarm_r","translation")"
    R"(:[-0.3,0,0],"children":[10]},{"name":"hand_r","translation":[-0.25,0,0]},{"name":"thigh_)"
    R"(l","translation":[0.1,-0.05,0],"children":[12]},{"name":"calf_l","translation":[0,-0.45,)"
    R"(0],"children":[13]},{"name":"foot_l","translation":[0,-0.45,0]},{"name":"thigh_r","trans)"
    R"(lation":[-0.1,-0.05,0],"children":[15]},{"name":"calf_r","translation":[0,-0.45,0],"chil)"
    R"(dren":[16]},{"name":"foot_r","translation":[0,-0.45,0]},{"name":"body","mesh":0,"skin":0)"
    R"(}],"skins":[{"joints":[0,1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16]}],"meshes":[{"primitive)"
    R"(s":[{"attributes":{"POSITION":0,"JOINTS_0":1,"WEIGHTS_0":2}}]}],"animations":[{"channels)"
    R"(":[{"sampler":0,"target":{"node":1,"path":"translation"}}],"samplers":[{"input":3,"outpu)"
    R"(t":4,"interpolation":"LINEAR"}]}],"buffers":[{"byteLength":140,"uri":"data:application/o)"
    R"(ctet-stream;base64,AAAAAAAAgD/NzMw9zczMPQAAgD/NzMw9AAAAAM3MjD/NzMw9AQAAAAAAAAABAAAAAAAAA)"
    R"(AEAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAIA/AAAAAAAAAAAAAAAAAAAAAAAAgD8AA)"
    R"(AAAAACAPwAAAAAAAAAAzcyMPwAAAAA="}],"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength)"
    R"(":36},{"buffer":0,"byteOffset":36,"byteLength":24},{"buffer":0,"byteOffset":60,"byteLeng)"
    R"(th":48},{"buffer":0,"byteOffset":108,"byteLength":8},{"buffer":0,"byteOffset":116,"byteL)"
    R"(ength":24}],"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","m)"
    R"(in":[0,1,0.1],"max":[0.1,1.1,0.1]},{"bufferView":1,"componentType":5123,"count":3,"type")"
    R"(:"VEC4"},{"bufferView":2,"componentType":5126,"count":3,"type":"VEC4"},{"bufferView":3,")"
    R"(componentType":5126,"count":2,"type":"SCALAR","min":[0],"max":[1]},{"bufferView":4,"comp)"
    R"(onentType":5126,"count":2,"type":"VEC3"}]})";

// Unreal's and Character Creator's rigs move the pelvis, not the root on the floor above
// which it hangs; a clip keeps only its root's translation, and took it from the skeleton's
// root: the rig's pelvis bob (and a jump) was lost. The H-Anim root's path is now the clip's.
TEST(ClipImport, ThePelvisPathOfARigWithARootOnTheFloorIsTheClips) {
  ScratchDir dir;
  ClipImportOptions options;
  options.sample_rate = 10.0;
  const sim::Clip clip = LoadClip(dir.Write("rising.gltf", kPelvisRisingClip), options);
  ASSERT_EQ(clip.frames.size(), 11u);  // 1 s at 10 Hz, both ends: it does not loop
  for (std::size_t f = 0; f < clip.frames.size(); ++f) {
    EXPECT_NEAR(clip.frames[f].root_translation.y(), 0.01 * f, 1e-6) << "frame " << f;
    EXPECT_NEAR(clip.frames[f].root_translation.x(), 0.0, 1e-9);
    EXPECT_NEAR(clip.frames[f].root_translation.z(), 0.0, 1e-9);
  }
  EXPECT_EQ(clip.skeleton->joint(clip.skeleton->Find(HAnimJoint::kHumanoidRoot)).name, "pelvis");
}

/// A rig as a tool names its joints, and what its family should map.
struct ToolRig {
  const char* tool;
  SkeletonFamily family;
  std::vector<std::string> names;
  int num_mapped;
  std::vector<std::pair<HAnimJoint, std::string>> expected;
};

// The rigs of the tools a designer's avatar most likely comes from, named as those tools
// name their bones (Blender's human metarig and the rig Rigify generates from it, with its
// control, ORG- and MCH- bones beside the DEF- bones that hold the skin; Unreal's UE5
// mannequin; a 3ds Max Biped; a VRoid Studio avatar with hair and skirt bones; Daz's Genesis
// 8 with its twist bones; Reallusion's Character Creator): each is detected, and the joints
// that bend the skin map.
TEST(SkeletonFamilies, MapsTheRigsOfTheToolsAvatarsComeFrom) {
  using H = HAnimJoint;
  const ToolRig rigs[] = {
      {"Rigify", SkeletonFamily::kBlender,
       Sided({"root", "torso", "hips", "chest", "neck", "head", "shoulder{side}", "spine_fk",
              "spine_fk.001", "MCH-spine", "ORG-spine", "ORG-thigh{side}", "ORG-shin{side}",
              "thigh_fk{side}", "thigh_ik{side}", "foot_ik{side}", "hand_ik{side}",
              "upper_arm_fk{side}", "DEF-spine", "DEF-spine.001", "DEF-spine.002",
              "DEF-spine.003", "DEF-spine.004", "DEF-spine.005", "DEF-spine.006",
              "DEF-thigh{side}", "DEF-thigh{side}.001", "DEF-shin{side}", "DEF-shin{side}.001",
              "DEF-foot{side}", "DEF-toe{side}", "DEF-shoulder{side}", "DEF-upper_arm{side}",
              "DEF-upper_arm{side}.001", "DEF-forearm{side}", "DEF-forearm{side}.001",
              "DEF-hand{side}"},
             ".L", ".R"),
       16,
       {{H::kHumanoidRoot, "DEF-spine"}, {H::kVl5, "DEF-spine.001"}, {H::kVc7, "DEF-spine.004"},
        {H::kSkullbase, "DEF-spine.006"}, {H::kLHip, "DEF-thigh.L"}, {H::kRKnee, "DEF-shin.R"},
        {H::kLShoulder, "DEF-upper_arm.L"}, {H::kRElbow, "DEF-forearm.R"},
        {H::kLRadiocarpal, "DEF-hand.L"}}},
      {"Blender metarig", SkeletonFamily::kBlender,
       Sided({"spine", "spine.001", "spine.002", "spine.003", "spine.004", "spine.005",
              "spine.006", "pelvis{side}", "thigh{side}", "shin{side}", "foot{side}",
              "toe{side}", "heel.02{side}", "breast{side}", "shoulder{side}", "upper_arm{side}",
              "forearm{side}", "hand{side}"},
             ".L", ".R"),
       16, {{H::kHumanoidRoot, "spine"}, {H::kRTalocrural, "foot.R"}}},
      {"Unreal UE5", SkeletonFamily::kUnreal,
       Sided({"root", "pelvis", "spine_01", "spine_02", "spine_03", "spine_04", "spine_05",
              "neck_01", "neck_02", "head", "clavicle{side}", "upperarm{side}",
              "upperarm_twist_01{side}", "lowerarm{side}", "lowerarm_twist_01{side}",
              "hand{side}", "thigh{side}", "thigh_twist_01{side}", "calf{side}",
              "calf_twist_01{side}", "foot{side}", "ball{side}", "ik_foot_root",
              "ik_hand_root"},
             "_l", "_r"),
       16,
       // The pelvis, not the root on the floor.
       {{H::kHumanoidRoot, "pelvis"}, {H::kLKnee, "calf_l"}, {H::kRShoulder, "upperarm_r"},
        {H::kVc7, "neck_01"}}},
      {"3ds Max Biped", SkeletonFamily::kMaxBiped,
       Sided({"Bip001", "Bip001 Pelvis", "Bip001 Spine", "Bip001 Spine1", "Bip001 Neck",
              "Bip001 Head", "Bip001 {side} Clavicle", "Bip001 {side} UpperArm",
              "Bip001 {side} Forearm", "Bip001 {side} Hand", "Bip001 {side} Finger0",
              "Bip001 {side} Thigh", "Bip001 {side} Calf", "Bip001 {side} Foot",
              "Bip001 {side} Toe0"},
             "L", "R"),
       17,
       {{H::kHumanoidRoot, "Bip001"}, {H::kSacroiliac, "Bip001 Pelvis"},
        {H::kVl5, "Bip001 Spine"}, {H::kLHip, "Bip001 L Thigh"},
        {H::kRRadiocarpal, "Bip001 R Hand"}}},
      {"VRoid Studio", SkeletonFamily::kVRoid,
       Sided({"Root", "J_Bip_C_Hips", "J_Bip_C_Spine", "J_Bip_C_Chest", "J_Bip_C_UpperChest",
              "J_Bip_C_Neck", "J_Bip_C_Head", "J_Adj_L_FaceEye", "J_Bip_{side}_Shoulder",
              "J_Bip_{side}_UpperArm", "J_Bip_{side}_LowerArm", "J_Bip_{side}_Hand",
              "J_Bip_{side}_UpperLeg", "J_Bip_{side}_LowerLeg", "J_Bip_{side}_Foot",
              "J_Bip_{side}_ToeBase", "J_Sec_Hair1_01", "J_Sec_{side}_SkirtBack0_01"},
             "L", "R"),
       16,
       {{H::kHumanoidRoot, "J_Bip_C_Hips"}, {H::kRShoulder, "J_Bip_R_UpperArm"},
        {H::kLTalocrural, "J_Bip_L_Foot"}}},
      {"Daz Genesis 8", SkeletonFamily::kDazGenesis,
       Sided({"hip", "pelvis", "{side}ThighBend", "{side}ThighTwist", "{side}Shin", "{side}Foot",
              "{side}Metatarsals", "abdomenLower", "abdomenUpper", "chestLower", "chestUpper",
              "neckLower", "neckUpper", "head", "{side}Collar", "{side}ShldrBend",
              "{side}ShldrTwist", "{side}ForearmBend", "{side}ForearmTwist", "{side}Hand"},
             "l", "r"),
       17,
       {{H::kHumanoidRoot, "hip"}, {H::kSacroiliac, "pelvis"}, {H::kLHip, "lThighBend"},
        {H::kVl5, "abdomenLower"}, {H::kVc7, "neckLower"}, {H::kRShoulder, "rShldrBend"},
        {H::kLElbow, "lForearmBend"}}},
      {"Character Creator 4", SkeletonFamily::kCharacterCreator,
       Sided({"CC_Base_BoneRoot", "CC_Base_Hip", "CC_Base_Pelvis", "CC_Base_{side}_Thigh",
              "CC_Base_{side}_Calf", "CC_Base_{side}_Foot", "CC_Base_{side}_ToeBase",
              "CC_Base_Waist", "CC_Base_Spine01", "CC_Base_Spine02", "CC_Base_NeckTwist01",
              "CC_Base_NeckTwist02", "CC_Base_Head", "CC_Base_{side}_Clavicle",
              "CC_Base_{side}_Upperarm", "CC_Base_{side}_Forearm", "CC_Base_{side}_Hand"},
             "L", "R"),
       17,
       {{H::kHumanoidRoot, "CC_Base_Hip"}, {H::kSacroiliac, "CC_Base_Pelvis"},
        {H::kVl5, "CC_Base_Waist"}, {H::kVc7, "CC_Base_NeckTwist01"},
        {H::kRKnee, "CC_Base_R_Calf"}, {H::kLRadiocarpal, "CC_Base_L_Hand"}}},
  };
  for (const ToolRig& rig : rigs) {
    SCOPED_TRACE(rig.tool);
    EXPECT_EQ(DetectFamily(rig.names), rig.family);
    int count = 0;
    std::map<HAnimJoint, std::string> mapped = Mapped(rig.family, rig.names, count);
    EXPECT_EQ(count, rig.num_mapped);
    for (const auto& [joint, name] : rig.expected) {
      EXPECT_EQ(mapped[joint], name) << sim::HAnimName(joint);
    }
  }
  // A biped renamed in Max keeps its bones' own names after its name, and is its root.
  EXPECT_EQ(LookUpJoint(SkeletonFamily::kMaxBiped, "Bip02 L Calf"), HAnimJoint::kLKnee);
  EXPECT_EQ(LookUpJoint(SkeletonFamily::kMaxBiped, "Bip02"), HAnimJoint::kHumanoidRoot);
  EXPECT_EQ(LookUpJoint(SkeletonFamily::kBlender, "ORG-thigh.L"), std::nullopt);
}

}  // namespace
}  // namespace costume::assets
