#pragma once
/// @file
/// Test oracle: which pixel centres a set of triangles covers once projected, computed on the
/// CPU with edge functions (no GL), and colour comparisons against the background.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "render/camera.h"
#include "render/image.h"
#include "render/scene_renderer.h"

namespace costume::render::testing {

/// Per pixel (row-major, top row first): 1 when the pixel centre lies inside a triangle.
struct CoverageMask {
  int width = 0, height = 0;
  std::vector<std::uint8_t> covered;
  bool At(int x, int y) const { return covered[y * width + x] != 0; }
  /// Every pixel within `radius` (Chebyshev) of (x, y) has coverage `value` (pixels outside
  /// the image count as uncovered).
  bool All(int x, int y, int radius, bool value) const {
    for (int dy = -radius; dy <= radius; ++dy) {
      for (int dx = -radius; dx <= radius; ++dx) {
        const int u = x + dx, v = y + dy;
        const bool c = u >= 0 && v >= 0 && u < width && v < height && At(u, v);
        if (c != value) return false;
      }
    }
    return true;
  }
};

/// Rasterises the meshes' triangles projected by ProjectToPixel (pixel centres at +0.5).
inline CoverageMask Rasterise(const std::vector<DrawMesh>& meshes, const Camera& camera,
                              int width, int height) {
  CoverageMask mask{width, height, std::vector<std::uint8_t>(width * height, 0)};
  for (const DrawMesh& mesh : meshes) {
    std::vector<Eigen::Vector2d> pixel(mesh.positions.size());
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
      pixel[i] = ProjectToPixel(camera, mesh.positions[i].cast<double>(), width, height).value();
    }
    for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
      const Eigen::Vector2d a = pixel[mesh.indices[t]], b = pixel[mesh.indices[t + 1]],
                            c = pixel[mesh.indices[t + 2]];
      const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
      if (area == 0.0) continue;
      const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
      const int x1 = std::min(width - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
      const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
      const int y1 = std::min(height - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
      const auto edge = [](const Eigen::Vector2d& p, const Eigen::Vector2d& q,
                           const Eigen::Vector2d& r) {
        return (q - p).x() * (r - p).y() - (q - p).y() * (r - p).x();
      };
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
          const Eigen::Vector2d p(x + 0.5, y + 0.5);
          const double w0 = edge(b, c, p) / area, w1 = edge(c, a, p) / area,
                       w2 = edge(a, b, p) / area;
          if (w0 >= 0 && w1 >= 0 && w2 >= 0) mask.covered[y * width + x] = 1;
        }
      }
    }
  }
  return mask;
}

/// The pixel differs from `background` (RGB in [0, 1]) by more than `tolerance` of 255 in
/// some channel.
inline bool DiffersFrom(const Image& image, int x, int y, const Eigen::Vector3f& background,
                        int tolerance = 6) {
  const std::uint8_t* p = image.Pixel(x, y);
  for (int c = 0; c < 3; ++c) {
    if (std::abs(p[c] - static_cast<int>(std::lround(background[c] * 255))) > tolerance) return true;
  }
  return false;
}

}  // namespace costume::render::testing
