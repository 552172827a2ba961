#include "assets/assimp_input.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <vector>

#include <assimp/DefaultIOSystem.h>
#include <assimp/MemoryIOWrapper.h>

#include "assets/import_units.h"
#include "sim_core/common/input_error.h"

namespace costume::assets {
namespace {

using nlohmann::json;

/// GLB's header and chunk tags (glTF 2.0, "GLB File Format Specification").
constexpr std::uint32_t kGlbMagic = 0x46546C67;      // "glTF"
constexpr std::uint32_t kGlbJsonChunk = 0x4E4F534A;  // "JSON"
constexpr std::size_t kGlbHeaderBytes = 12;
constexpr std::size_t kGlbChunkHeaderBytes = 8;
constexpr int kFloatComponent = 5126;
constexpr std::size_t kMatrixBytes = 16 * sizeof(float);

std::string Base64(const std::string& bytes) {
  static constexpr char kDigits[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string text;
  text.reserve((bytes.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    std::uint32_t group = static_cast<std::uint8_t>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) group |= static_cast<std::uint8_t>(bytes[i + 1]) << 8;
    if (i + 2 < bytes.size()) group |= static_cast<std::uint8_t>(bytes[i + 2]);
    text += kDigits[(group >> 18) & 63];
    text += kDigits[(group >> 12) & 63];
    text += i + 1 < bytes.size() ? kDigits[(group >> 6) & 63] : '=';
    text += i + 2 < bytes.size() ? kDigits[group & 63] : '=';
  }
  return text;
}

/// `count` 4×4 identity matrices as glTF stores them: little-endian floats, column-major.
std::string IdentityMatrices(std::size_t count) {
  std::array<float, 16> identity{};
  for (int d = 0; d < 4; ++d) identity[static_cast<std::size_t>(5 * d)] = 1.0f;
  std::string one(kMatrixBytes, '\0');
  std::memcpy(one.data(), identity.data(), kMatrixBytes);
  std::string all;
  for (std::size_t i = 0; i < count; ++i) all += one;
  return all;
}

/// The number of elements of accessor `index`, or nullopt when the file does not say.
std::optional<std::uint64_t> AccessorCount(const json& gltf, const json& index) {
  const auto accessors = gltf.find("accessors");
  if (!index.is_number_unsigned() || accessors == gltf.end() || !accessors->is_array()) {
    return std::nullopt;
  }
  const auto i = index.get<std::uint64_t>();
  if (i >= accessors->size()) return std::nullopt;
  const json& accessor = (*accessors)[i];
  const auto count = accessor.is_object() ? accessor.find("count") : accessor.end();
  if (count == accessor.end() || !count->is_number_unsigned()) return std::nullopt;
  return count->get<std::uint64_t>();
}

/// Appends `item` to the array `key` of `gltf` (made when absent); its index, or -1 when
/// `key` holds something else.
long long Append(json& gltf, const char* key, json item) {
  json& list = gltf[key];
  if (list.is_null()) list = json::array();
  if (!list.is_array()) return -1;
  list.push_back(std::move(item));
  return static_cast<long long>(list.size()) - 1;
}

/// The skins of `gltf` without inverse bind matrices, and the most joints among them.
/// Throws for a skin with fewer matrices than joints.
std::vector<json*> SkinsWithoutMatrices(json& gltf, std::size_t& most_joints,
                                        const std::string& path) {
  std::vector<json*> lacking;
  json& skins = gltf["skins"];
  for (std::size_t s = 0; skins.is_array() && s < skins.size(); ++s) {
    json& skin = skins[s];
    const auto joints = skin.is_object() ? skin.find("joints") : skin.end();
    if (joints == skin.end() || !joints->is_array() || joints->empty()) continue;
    const auto matrices = skin.find("inverseBindMatrices");
    if (matrices == skin.end()) {
      lacking.push_back(&skin);
      most_joints = std::max(most_joints, joints->size());
      continue;
    }
    const std::optional<std::uint64_t> count = AccessorCount(gltf, *matrices);
    if (count && *count < joints->size()) {
      const auto name = skin.find("name");
      throw sim::InputError(
          path + ": skin " + std::to_string(s) +
          (name != skin.end() && name->is_string() ? " '" + name->get<std::string>() + "'" : "") +
          " has " + std::to_string(*count) + " inverse bind matrices for " +
          std::to_string(joints->size()) + " joints (allowed: one per joint)");
    }
  }
  return lacking;
}

/// The amended JSON text, or nullopt when no skin lacks matrices or the JSON is not a glTF
/// this can amend.
std::optional<std::string> AmendJson(const std::string& text, const std::string& path) {
  json gltf = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!gltf.is_object()) return std::nullopt;
  if (!gltf.contains("skins")) return std::nullopt;
  std::size_t most_joints = 0;
  const std::vector<json*> lacking = SkinsWithoutMatrices(gltf, most_joints, path);
  if (lacking.empty()) return std::nullopt;
  const std::size_t bytes = most_joints * kMatrixBytes;
  const long long buffer = Append(
      gltf, "buffers",
      {{"byteLength", bytes},
       {"uri", "data:application/octet-stream;base64," + Base64(IdentityMatrices(most_joints))}});
  const long long view =
      Append(gltf, "bufferViews", {{"buffer", buffer}, {"byteLength", bytes}});
  if (buffer < 0 || view < 0) return std::nullopt;
  for (json* skin : lacking) {
    const long long accessor =
        Append(gltf, "accessors",
               {{"bufferView", view}, {"componentType", kFloatComponent},
                {"count", (*skin)["joints"].size()}, {"type", "MAT4"}});
    if (accessor < 0) return std::nullopt;
    (*skin)["inverseBindMatrices"] = accessor;
  }
  return gltf.dump();
}

std::uint32_t ReadWord(const std::string& bytes, std::size_t at) {
  std::uint32_t word = 0;
  for (int b = 3; b >= 0; --b) word = word << 8 | static_cast<std::uint8_t>(bytes[at + b]);
  return word;
}

void AppendWord(std::string& bytes, std::uint32_t word) {
  for (int b = 0; b < 4; ++b) bytes += static_cast<char>(word >> (8 * b) & 0xFF);
}

/// The GLB with its JSON chunk amended, the chunks after it unchanged.
std::optional<std::string> AmendGlb(const std::string& bytes, const std::string& path) {
  constexpr std::size_t kJsonStart = kGlbHeaderBytes + kGlbChunkHeaderBytes;
  if (bytes.size() < kJsonStart || ReadWord(bytes, 0) != kGlbMagic ||
      ReadWord(bytes, kGlbHeaderBytes + 4) != kGlbJsonChunk) {
    return std::nullopt;
  }
  const std::size_t json_bytes = ReadWord(bytes, kGlbHeaderBytes);
  if (json_bytes > bytes.size() - kJsonStart) return std::nullopt;
  std::optional<std::string> text = AmendJson(bytes.substr(kJsonStart, json_bytes), path);
  if (!text) return std::nullopt;
  // Chunks are 4-byte aligned; JSON is padded with spaces.
  text->append((4 - text->size() % 4) % 4, ' ');
  const std::string rest = bytes.substr(kJsonStart + json_bytes);
  std::string glb = bytes.substr(0, 8);
  AppendWord(glb, static_cast<std::uint32_t>(kJsonStart + text->size() + rest.size()));
  AppendWord(glb, static_cast<std::uint32_t>(text->size()));
  AppendWord(glb, kGlbJsonChunk);
  return glb + *text + rest;
}

/// The file system assimp reads through, with the file `path` holding `bytes` (a file in
/// its place, or one that is not on disk at all).
class SubstitutedFileSystem : public Assimp::DefaultIOSystem {
 public:
  SubstitutedFileSystem(std::string path, std::string bytes)
      : path_(std::move(path)), bytes_(std::move(bytes)) {}

  bool Exists(const char* file) const override {
    return IsSubstitute(file) || DefaultIOSystem::Exists(file);
  }

  Assimp::IOStream* Open(const char* file, const char* mode) override {
    if (!IsSubstitute(file)) return DefaultIOSystem::Open(file, mode);
    return new Assimp::MemoryIOStream(reinterpret_cast<const std::uint8_t*>(bytes_.data()),
                                      bytes_.size());
  }

 private:
  bool IsSubstitute(const char* file) const {
    return file == path_ || ComparePaths(file, path_.c_str());
  }

  std::string path_;
  std::string bytes_;
};

}  // namespace

std::optional<std::string> WithExplicitBindMatrices(const std::string& bytes, bool binary,
                                                    const std::string& path) {
  return binary ? AmendGlb(bytes, path) : AmendJson(bytes, path);
}

std::optional<std::string> WithExplicitBindShapes(const std::string& text) {
  static constexpr char kIdentity[] =
      "<bind_shape_matrix>1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1</bind_shape_matrix>";
  std::string amended;
  std::size_t copied = 0;
  for (std::size_t at = text.find("<skin"); at != std::string::npos;
       at = text.find("<skin", at + 1)) {
    const std::size_t name_end = at + 5;
    if (name_end >= text.size() ||
        (text[name_end] != '>' && !std::isspace(static_cast<unsigned char>(text[name_end])))) {
      continue;  // another element whose name starts so
    }
    const std::size_t open_end = text.find('>', name_end);
    if (open_end == std::string::npos) break;
    if (text[open_end - 1] == '/') continue;  // <skin ... />: nothing to bind
    const std::size_t close = text.find("</skin>", open_end);
    const std::size_t shape = text.find("<bind_shape_matrix", open_end);
    if (shape != std::string::npos && shape < close) continue;
    // The schema puts <bind_shape_matrix> first among the skin's children.
    amended.append(text, copied, open_end + 1 - copied);
    amended += kIdentity;
    copied = open_end + 1;
  }
  if (copied == 0) return std::nullopt;
  amended.append(text, copied);
  return amended;
}

std::string PrepareAssimpInput(Assimp::Importer& importer, const std::string& path) {
  const std::string extension = LowerExtension(path);
  const bool vrm = extension == ".vrm";
  const bool binary = vrm || extension == ".glb";
  const bool gltf = binary || extension == ".gltf";
  if (!gltf && extension != ".dae") return path;
  std::ifstream file(path, std::ios::binary);
  std::string bytes{std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
  std::optional<std::string> amended;
  if (!gltf) {
    amended = WithExplicitBindShapes(bytes);
  } else if (bytes.find("\"skins\"") != std::string::npos) {
    // A skin is named in the JSON as "skins" (a GLB's JSON is plain text too): most files
    // without one are passed over unparsed.
    amended = WithExplicitBindMatrices(bytes, binary, path);
  }
  // assimp picks its reader by the extension, and reads a VRM (a GLB with VRM's own
  // extension in its JSON) only under the name ".glb".
  const std::string name = vrm ? path + ".glb" : path;
  if (amended || vrm) {
    importer.SetIOHandler(
        new SubstitutedFileSystem(name, amended ? std::move(*amended) : std::move(bytes)));
  }
  return name;
}

}  // namespace costume::assets
