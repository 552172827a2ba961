#pragma once
/// @file
/// Helpers shared by the importer tests: the real assets in ../shared/data, scratch folders,
/// damaged copies of files, and measurements of skeletons and poses.

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "sim_core/avatar/pose.h"
#include "sim_core/avatar/skeleton.h"
#include "tests/support/shared_data.h"

namespace costume::assets::testing {

namespace fs = std::filesystem;

/// The shared test data folder.
inline const fs::path& kData = ::costume::test::kSharedData;

inline bool HaveData(const fs::path& relative) { return fs::exists(kData / relative); }

#define SKIP_WITHOUT(relative)                                                        \
  if (!::costume::assets::testing::HaveData(relative))                                \
  GTEST_SKIP() << "test data " << (::costume::assets::testing::kData / (relative))    \
               << " not present"

/// The bytes of the file at `source`.
inline std::string ReadBytes(const fs::path& source) {
  std::ifstream in(source, std::ios::binary);
  std::ostringstream all;
  all << in.rdbuf();
  return all.str();
}

/// A fresh folder for one test's files, removed afterwards.
class ScratchDir {
 public:
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() /
            ("import_test_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" +
             info->name());
    fs::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;

  /// Writes `content` to the file `name` in this folder and returns its path.
  std::string Write(const std::string& name, const std::string& content) const {
    const fs::path file = path_ / name;
    std::ofstream(file, std::ios::binary) << content;
    return file.string();
  }
  /// The first half of the bytes of `source`, as `name`.
  std::string WriteTruncated(const std::string& name, const fs::path& source) const {
    const std::string bytes = ReadBytes(source);
    return Write(name, bytes.substr(0, bytes.size() / 2));
  }
  /// `size` random bytes (fixed seed), as `name`.
  std::string WriteGarbage(const std::string& name, std::size_t size, unsigned seed = 7) const {
    std::mt19937 random(seed);
    std::string bytes(size, '\0');
    for (char& c : bytes) c = static_cast<char>(random() & 0xff);
    return Write(name, bytes);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

/// Rest height of a skeleton: highest minus lowest joint [m].
inline double RestHeight(const sim::Skeleton& skeleton) {
  double lo = 1e9, hi = -1e9;
  for (const Eigen::Isometry3d& frame : skeleton.rest_world()) {
    lo = std::min(lo, frame.translation().y());
    hi = std::max(hi, frame.translation().y());
  }
  return hi - lo;
}

/// The rest position of a mapped H-Anim joint.
inline Eigen::Vector3d RestOf(const sim::Skeleton& skeleton, sim::HAnimJoint joint) {
  return skeleton.rest_world()[skeleton.Find(joint)].translation();
}

}  // namespace costume::assets::testing
