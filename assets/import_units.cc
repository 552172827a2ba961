#include "assets/import_units.h"

#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "sim_core/common/input_error.h"

namespace costume::assets {

Eigen::Matrix3d UpRotation(UpAxis up) {
  if (up != UpAxis::kZ) return Eigen::Matrix3d::Identity();
  Eigen::Matrix3d rotation;
  rotation << 1, 0, 0,  //
      0, 0, 1,          //
      0, -1, 0;
  return rotation;
}

double GuessMetresPerUnit(double height_in_file_units) {
  if (!std::isfinite(height_in_file_units) || height_in_file_units <= 0.0) return 1.0;
  constexpr double kTypicalHeight = 1.7;
  constexpr std::array<double, 5> kUnits = {1.0, 0.1, 0.01, 0.001, 0.0254};
  double best = 1.0;
  double best_error = INFINITY;
  for (double unit : kUnits) {
    const double error = std::abs(std::log(height_in_file_units * unit / kTypicalHeight));
    if (error < best_error) {
      best = unit;
      best_error = error;
    }
  }
  return best;
}

void ValidateScaleOption(const std::string& path, double scale) {
  if (scale == 0.0) return;
  sim::RequirePositive(path + ": scale (0 to detect)", scale, "m per file unit");
}

void RequireReadableFile(const std::string& path, const std::string& what) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) {
    // A folder or a device given where a file belongs is a different mistake from a typo.
    const bool exists = std::filesystem::exists(path, error);
    throw sim::InputError(path + ": cannot read the " + what + ": " +
                          (exists ? "not a regular file" : "no such file"));
  }
  std::ifstream stream(path, std::ios::binary);
  if (!stream) throw sim::InputError(path + ": cannot read the " + what + ": cannot be opened");
}

std::string ReadWholeFile(const std::string& path, const std::string& what) {
  RequireReadableFile(path, what);
  std::ifstream stream(path, std::ios::binary);
  std::ostringstream content;
  content << stream.rdbuf();
  if (stream.bad()) throw sim::InputError(path + ": cannot read the " + what + ": read error");
  return content.str();
}

std::string LowerExtension(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension;
}

}  // namespace costume::assets
