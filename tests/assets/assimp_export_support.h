#pragma once
/// @file
/// Real FBX and Collada files for the importer tests, made at test time from the CesiumMan
/// glTF of ../shared/data by assimp's own exporters (the shared data holds no FBX or Collada
/// file). assimp 5.2.5's exporters get three things wrong, each worked around here so that
/// the files say what a correct exporter would write (docs/assets.md, "Files converted by
/// assimp"):
/// - both write key times in the scene's ticks where seconds are due (glTF's ticks are
///   milliseconds, so the 2 s walk would become 2,000 s): the scene's animation is put in
///   seconds (1 tick per second) before export;
/// - the binary FBX exporter ends nested nodes without the 25-byte null record (assimp issue
///   4686, fixed after 5.2.5), so that assimp's own reader refuses the file: RepairBinaryFbx
///   puts the records back;
/// - the FBX exporter drops the scene root's transform (CesiumMan's z-up-to-y-up turn) and
///   always declares centimetres, y up: the scenes are prepared so that the declaration is
///   true (see ExportCesiumMan).
/// Tests only: links assimp directly.

#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>
#include <assimp/scene.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>

#include "tests/assets/import_test_support.h"

namespace costume::assets::testing {

/// How the CesiumMan glTF is converted.
enum class Conversion {
  /// Binary FBX in centimetres, y up (as Maya writes them): the file's default declaration.
  kFbxBinaryCentimetres,
  /// ASCII FBX in metres, z up (as Blender writes them): UnitScaleFactor 100 and UpAxis 2
  /// written into the exported text.
  kFbxAsciiMetresZUp,
  /// Collada in centimetres, z up: <unit meter="0.01"> written into the exported text.
  kColladaCentimetres,
};

inline const char* ConversionName(Conversion conversion) {
  switch (conversion) {
    case Conversion::kFbxBinaryCentimetres: return "binary FBX, cm, y up";
    case Conversion::kFbxAsciiMetresZUp: return "ASCII FBX, m, z up";
    case Conversion::kColladaCentimetres: return "Collada, cm, z up";
  }
  return "?";
}

/// Every conversion, in the order the tests run them.
inline constexpr Conversion kConversions[] = {Conversion::kFbxBinaryCentimetres,
                                              Conversion::kFbxAsciiMetresZUp,
                                              Conversion::kColladaCentimetres};

/// The converted file's name (its extension tells assimp the format).
inline std::string ConvertedName(Conversion conversion) {
  return conversion == Conversion::kColladaCentimetres
             ? "man.dae"
             : (conversion == Conversion::kFbxBinaryCentimetres ? "man.fbx" : "man_ascii.fbx");
}

namespace detail {

inline void WriteBytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

/// Replaces the one occurrence of `from` in `text` by `to`; throws if it is not there.
inline void ReplaceOnce(std::string& text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  if (at == std::string::npos) throw std::runtime_error("exported file lacks '" + from + "'");
  text.replace(at, from.size(), to);
}

/// Every animation in seconds: one tick per second (the exporters' time unit bug).
inline void PutAnimationsInSeconds(aiScene& scene) {
  for (unsigned a = 0; a < scene.mNumAnimations; ++a) {
    aiAnimation& animation = *scene.mAnimations[a];
    const double ticks_per_second = animation.mTicksPerSecond > 0 ? animation.mTicksPerSecond : 25.0;
    animation.mDuration /= ticks_per_second;
    animation.mTicksPerSecond = 1.0;
    for (unsigned c = 0; c < animation.mNumChannels; ++c) {
      aiNodeAnim& channel = *animation.mChannels[c];
      for (unsigned k = 0; k < channel.mNumPositionKeys; ++k) channel.mPositionKeys[k].mTime /= ticks_per_second;
      for (unsigned k = 0; k < channel.mNumRotationKeys; ++k) channel.mRotationKeys[k].mTime /= ticks_per_second;
      for (unsigned k = 0; k < channel.mNumScalingKeys; ++k) channel.mScalingKeys[k].mTime /= ticks_per_second;
    }
  }
}

inline void ScaleTranslation(aiMatrix4x4& m, float factor) {
  m.a4 *= factor;
  m.b4 *= factor;
  m.c4 *= factor;
}

/// Changes the unit of every length in the scene (vertices, node and bind translations,
/// position keys) by `factor`: 100 turns metres into centimetres.
inline void ScaleLengths(aiScene& scene, float factor) {
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) {
    aiMesh& mesh = *scene.mMeshes[m];
    for (unsigned v = 0; v < mesh.mNumVertices; ++v) mesh.mVertices[v] *= factor;
    for (unsigned b = 0; b < mesh.mNumBones; ++b) ScaleTranslation(mesh.mBones[b]->mOffsetMatrix, factor);
  }
  struct Walk {
    static void Nodes(aiNode& node, float f) {
      ScaleTranslation(node.mTransformation, f);
      for (unsigned c = 0; c < node.mNumChildren; ++c) Nodes(*node.mChildren[c], f);
    }
  };
  Walk::Nodes(*scene.mRootNode, factor);
  for (unsigned a = 0; a < scene.mNumAnimations; ++a) {
    const aiAnimation& animation = *scene.mAnimations[a];
    for (unsigned c = 0; c < animation.mNumChannels; ++c) {
      aiNodeAnim& channel = *animation.mChannels[c];
      for (unsigned k = 0; k < channel.mNumPositionKeys; ++k) channel.mPositionKeys[k].mValue *= factor;
    }
  }
}

/// Puts a new identity root above the scene's root, so that an exporter that drops the
/// root's transform keeps the old root's.
inline void WrapRoot(aiScene& scene) {
  aiNode* root = new aiNode("converted_root");
  root->mNumChildren = 1;
  root->mChildren = new aiNode*[1]{scene.mRootNode};
  scene.mRootNode->mParent = root;
  scene.mRootNode = root;
}

/// Copies one binary FBX node record (FBX 7.5: 64-bit offsets) from `in` at `at` to `out`,
/// closing it with the 25-byte null record when it has children or is an object (a child
/// of "Objects": every object has a body, an empty one too, such as an AnimationLayer's,
/// which assimp's reader requires); returns the offset after the input record.
inline std::uint64_t CopyFbxNode(const std::string& in, std::uint64_t at, bool is_object,
                                 std::string& out) {
  std::uint64_t end = 0, property_bytes = 0;
  std::memcpy(&end, in.data() + at, 8);
  std::memcpy(&property_bytes, in.data() + at + 16, 8);
  const std::uint64_t name_length = static_cast<unsigned char>(in[at + 24]);
  const std::uint64_t children = at + 25 + name_length + property_bytes;
  if (end > in.size() || children > end) throw std::runtime_error("malformed FBX record");
  const bool holds_objects = in.compare(at + 25, name_length, "Objects") == 0;
  const std::size_t start = out.size();
  out.append(in, at, children - at);
  for (std::uint64_t child = children; child < end;) child = CopyFbxNode(in, child, holds_objects, out);
  if (children < end || is_object) out.append(25, '\0');
  const std::uint64_t new_end = out.size();
  std::memcpy(out.data() + start, &new_end, 8);
  return end;
}

}  // namespace detail

/// Rewrites a binary FBX 7.5 file from assimp 5.2.5's exporter with the null records that
/// close nested nodes and objects, which the exporter leaves out.
inline void RepairBinaryFbx(const std::filesystem::path& path) {
  const std::string in = ReadBytes(path);
  constexpr std::uint64_t kHeader = 27;
  std::string out = in.substr(0, kHeader);
  std::uint64_t at = kHeader;
  for (std::uint64_t end = 0; at + 8 <= in.size(); at = detail::CopyFbxNode(in, at, false, out)) {
    std::memcpy(&end, in.data() + at, 8);
    if (end == 0) break;  // the top level's own null record, then the footer
  }
  out.append(in, at, std::string::npos);
  detail::WriteBytes(path, out);
}

/// Converts the glTF/GLB `source` with assimp's exporter to `target` (its extension .fbx or
/// .dae; the Collada exporter writes the texture beside it); see Conversion for the unit and up axis each file declares. With `repair` false
/// the binary FBX is left as assimp 5.2.5 writes it (unreadable). Throws std::runtime_error
/// when assimp cannot read or write.
inline void ExportCesiumMan(const std::filesystem::path& source, const std::filesystem::path& target,
                            Conversion conversion, bool repair = true) {
  Assimp::Importer importer;
  if (importer.ReadFile(source.string(), 0) == nullptr) {
    throw std::runtime_error("assimp cannot read " + source.string() + ": " + importer.GetErrorString());
  }
  std::unique_ptr<aiScene> scene(importer.GetOrphanedScene());
  detail::PutAnimationsInSeconds(*scene);
  const char* format = "collada";
  switch (conversion) {
    case Conversion::kFbxBinaryCentimetres:
      format = "fbx";
      detail::WrapRoot(*scene);  // keeps CesiumMan's turn to y up
      detail::ScaleLengths(*scene, 100.0f);
      break;
    case Conversion::kFbxAsciiMetresZUp:
      format = "fbxa";
      // Without the glTF's turn to y up, the body stands along z, as in Blender.
      scene->mRootNode->mTransformation = aiMatrix4x4();
      detail::WrapRoot(*scene);
      break;
    case Conversion::kColladaCentimetres:
      detail::ScaleLengths(*scene, 100.0f);
      break;
  }
  Assimp::Exporter exporter;
  if (exporter.Export(scene.get(), format, target.string()) != aiReturn_SUCCESS) {
    throw std::runtime_error("assimp cannot write " + target.string() + ": " + exporter.GetErrorString());
  }
  std::string text;
  switch (conversion) {
    case Conversion::kFbxBinaryCentimetres:
      if (repair) RepairBinaryFbx(target);
      break;
    case Conversion::kFbxAsciiMetresZUp:
      text = ReadBytes(target);
      detail::ReplaceOnce(text, "P: \"UpAxis\", \"int\", \"Integer\", \"\", 1",
                          "P: \"UpAxis\", \"int\", \"Integer\", \"\", 2");
      detail::ReplaceOnce(text, "P: \"UnitScaleFactor\", \"double\", \"Number\", \"\", 1\n",
                          "P: \"UnitScaleFactor\", \"double\", \"Number\", \"\", 100\n");
      detail::WriteBytes(target, text);
      break;
    case Conversion::kColladaCentimetres:
      text = ReadBytes(target);
      detail::ReplaceOnce(text, "<unit name=\"meter\" meter=\"1\" />",
                          "<unit name=\"centimeter\" meter=\"0.01\" />");
      detail::WriteBytes(target, text);
      break;
  }
}

}  // namespace costume::assets::testing
