#pragma once
/// @file
/// The real assets of ../shared/data (each with its licence), which tests may use but the
/// product must not need. Tests run from the repository root (WORKING_DIRECTORY in
/// tests/CMakeLists.txt), so the folder is named relative to it; a test needing a file from it
/// skips when the file is absent (a clone without the shared folder, as on CI).

#include <filesystem>

namespace costume::test {

inline const std::filesystem::path kSharedData = "../shared/data";

}  // namespace costume::test
