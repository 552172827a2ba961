#include "assets/frame_writer.h"

#include <cstdio>
#include <fstream>
#include <system_error>

#include "sim_core/common/input_error.h"

namespace costume::assets {

void WriteObjFrame(const std::filesystem::path& path, const sim::ClothModel& model,
                   const sim::Points& positions, const std::vector<sim::GarmentRange>& garments,
                   const sim::AvatarMotion* avatar) {
  const std::filesystem::path temporary = path.string() + ".part";
  {
    std::ofstream out(temporary);
    if (!out) {
      throw sim::InputError(path.string() + ": cannot open for writing (check that the folder " +
                            "exists and is writable)");
    }
    out << "# Costume Designer cloth frame; units: metres, y up\n";
    char line[128];
    for (Eigen::Index i = 0; i < positions.rows(); ++i) {
      std::snprintf(line, sizeof(line), "v %.9g %.9g %.9g\n", positions(i, 0), positions(i, 1),
                    positions(i, 2));
      out << line;
    }
    for (const sim::GarmentRange& g : garments) {
      out << "o " << g.name << "\n";
      for (int t = g.first_triangle; t < g.first_triangle + g.num_triangles; ++t) {
        const Eigen::Vector3i& tri = model.triangles()[t];
        out << "f " << tri[0] + 1 << ' ' << tri[1] + 1 << ' ' << tri[2] + 1 << '\n';
      }
    }
    if (avatar) {
      const sim::Points& skin = avatar->vertices();
      for (Eigen::Index i = 0; i < skin.rows(); ++i) {
        std::snprintf(line, sizeof(line), "v %.6g %.6g %.6g\n", skin(i, 0), skin(i, 1), skin(i, 2));
        out << line;
      }
      out << "o avatar\n";
      const Eigen::Index base = positions.rows() + 1;
      for (const Eigen::Vector3i& tri : avatar->avatar().triangles()) {
        out << "f " << tri[0] + base << ' ' << tri[1] + base << ' ' << tri[2] + base << '\n';
      }
    }
    if (!out) throw sim::InputError(temporary.string() + ": write failed (disk full?)");
  }
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error) throw sim::InputError(path.string() + ": cannot rename from .part: " + error.message());
}

}  // namespace costume::assets
