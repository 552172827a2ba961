#pragma once
/// @file
/// sim_core's geometry (avatar skin, cloth state) as the renderer's DrawMesh, for the
/// thumbnails and the GUI's 3D view.

#include <vector>

#include <Eigen/Core>

#include "render/scene_renderer.h"
#include "sim_core/cloth/cloth_model.h"

namespace costume::render {

/// The avatar's skin colour in thumbnails and the GUI (RGB in [0, 1]).
inline const Eigen::Vector3f kSkinColour{0.87f, 0.70f, 0.58f};
/// The default cloth colour (RGB in [0, 1]).
inline const Eigen::Vector3f kClothColour{0.25f, 0.42f, 0.75f};

/// A DrawMesh of `positions` (n×3) [m] and `triangles` (indices into positions, assumed
/// valid), coloured `colour`; two-sided for cloth.
DrawMesh ToDrawMesh(const sim::Points& positions, const std::vector<Eigen::Vector3i>& triangles,
                    const Eigen::Vector3f& colour, bool two_sided);

/// Copies new positions (n×3) [m] into `mesh`, keeping its triangles: the per-frame update of
/// a moving avatar or cloth. Allocates only when the vertex count changed.
void UpdatePositions(DrawMesh& mesh, const sim::Points& positions);

}  // namespace costume::render
