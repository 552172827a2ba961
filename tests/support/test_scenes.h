#pragma once
/// @file
/// Small scenes for tests, built directly (no file), so each test states its physics.

#include <string>

#include "sim_core/scene/scene_description.h"

namespace costume::test {

/// A 6 cm, 7 × 7 patch centred on `centre`, its rows along `u`, its columns along `v` (unit,
/// perpendicular) [m].
inline sim::LatticePanel SmallPatch(const Eigen::Vector3d& centre, const Eigen::Vector3d& u,
                                    const Eigen::Vector3d& v) {
  sim::LatticePanel panel;
  panel.width = panel.height = 0.06;
  panel.cols = panel.rows = 7;
  panel.u_axis = u;
  panel.v_axis = v;
  panel.origin = centre - 0.03 * u - 0.03 * v;
  return panel;
}

/// The benchmark's hang scene (1 m sheet, two corners pinned) at n×n with `material`.
inline sim::SceneDescription HangScene(int n, const sim::Material& material = {}) {
  sim::SceneDescription scene;
  scene.name = "hang";
  sim::GarmentSpec garment;
  garment.name = "sheet";
  garment.material = material.name;
  garment.panel = sim::LatticePanel{};
  garment.panel->cols = garment.panel->rows = n;
  garment.pin_points = {Eigen::Vector3d(-0.5, 0, -0.5), Eigen::Vector3d(0.5, 0, -0.5)};
  scene.materials.push_back(material);
  scene.garments.push_back(garment);
  return scene;
}

/// The benchmark's drape scene: the sheet 0.5 m above a sphere of radius 0.25 m.
inline sim::SceneDescription DrapeScene(int n, const sim::Material& material = {}) {
  sim::SceneDescription scene = HangScene(n, material);
  scene.name = "drape";
  scene.garments[0].pin_points.clear();
  scene.garments[0].panel->origin = Eigen::Vector3d(-0.5, 0.5, -0.5);
  scene.spheres.push_back(sim::SphereObstacleSpec{});
  return scene;
}

/// Scene-file text (docs/scene_format.md) for the multi-process tests: a 1 m sheet of n×n
/// particles built already hanging in the plane z = −0.5 from its two top corners, PCG at
/// tolerance 1e-3, no strain limit; `material` is a `[[material]]` table named "cloth".
inline std::string HangingSheetScene(int n, const std::string& material) {
  return "name = \"hanging\"\nduration = 60.0\n"
         "[solver]\nmethod = \"pcg\"\ntolerance = 1e-3\nstrain_limit = 0.0\n" +
         material +
         "[[garment]]\nname = \"sheet\"\nmaterial = \"cloth\"\n"
         "pin_points = [[-0.5, 0, -0.5], [0.5, 0, -0.5]]\n"
         "[garment.panel]\norigin = [-0.5, 0, -0.5]\nu_axis = [1, 0, 0]\n"
         "v_axis = [0, -1, 0]\nsize = [1.0, 1.0]\nresolution = [" +
         std::to_string(n) + ", " + std::to_string(n) + "]\n";
}

/// The `[[material]]` table of stiff cotton named "cloth", for HangingSheetScene.
inline const std::string kStiffCottonCloth =
    "[[material]]\nname = \"cloth\"\nbase = \"stiff_cotton\"\n";

}  // namespace costume::test
