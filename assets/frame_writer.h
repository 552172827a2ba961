#pragma once
/// @file
/// Writes cloth frames to files a 3D tool opens (Wavefront OBJ, one object per garment).

#include <filesystem>
#include <vector>

#include "sim_core/cloth/cloth_model.h"
#include "sim_core/scene/simulation.h"

namespace costume::assets {

/// Writes `positions` [m] with the model's triangles as an OBJ file at `path`, one `o` group
/// per garment, and the avatar's skinned surface as an `o avatar` group when `avatar` is
/// given. Written to a temporary file first and renamed, so a reader never sees half a
/// frame. Throws sim::InputError naming the path when it cannot be written.
void WriteObjFrame(const std::filesystem::path& path, const sim::ClothModel& model,
                   const sim::Points& positions, const std::vector<sim::GarmentRange>& garments,
                   const sim::AvatarMotion* avatar = nullptr);

}  // namespace costume::assets
