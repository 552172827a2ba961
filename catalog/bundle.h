#pragma once
/// @file
/// A bundle: several files stored as one asset's bytes, for formats that need more than one
/// file (MakeHuman's base.obj + .mhskel + .mhw; a DeepMimic motion and its character file; a
/// garment scene file and the mesh it names). Layout, all text headers in ASCII:
///   "COSTUME-BUNDLE 1\n"
///   per file: "<name>\n<size in bytes, decimal>\n" then the bytes, then "\n"
/// Names are plain file names (no '/', '\\', "." or ".."), so unpacking into a folder cannot
/// write outside it.

#include <cstdint>
#include <string>
#include <vector>

namespace costume::catalog {

struct BundleFile {
  /// A plain file name ("base.obj").
  std::string name;
  std::vector<std::uint8_t> bytes;
};

/// True when `bytes` start with the bundle header.
bool IsBundle(const std::vector<std::uint8_t>& bytes);

/// The bytes of a bundle of `files`. Throws sim::InputError for a name that is not a plain
/// file name or repeated.
std::vector<std::uint8_t> PackBundle(const std::vector<BundleFile>& files);

/// The files of a bundle. Throws sim::InputError naming `source` for a malformed bundle.
std::vector<BundleFile> UnpackBundle(const std::vector<std::uint8_t>& bytes,
                                     const std::string& source);

}  // namespace costume::catalog
