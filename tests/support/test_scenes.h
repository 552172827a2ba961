#pragma once
/// @file
/// Small scenes for tests, built directly (no file), so each test states its physics.

#include "sim_core/scene/scene_description.h"

namespace costume::test {

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

}  // namespace costume::test
