/// @file
/// The superquadric collider's distance maps (superquadric_collider.h): sizing a segment's
/// map, drawing it from the skinned triangles, packing, storing and reusing drawings, and
/// reading it along a ray (ProbeShell, declared with the collider for its tests). Internal
/// to the collider.

#pragma once

#include <Eigen/Core>

#include "sim_core/collision/skin_map_cache.h"
#include "sim_core/collision/superquadric.h"
#include "sim_core/collision/superquadric_collider.h"

namespace costume::sim {

/// Floor of the ray/skin-normal cosine: a ray grazing the skin would otherwise turn a
/// millimetre of thickness into metres of radial shell.
inline constexpr double kMinSkinCosine = 0.1;

/// The node grid on the bounding box's faces: rays, the superquadric's radius along each,
/// the faces' node tables and the node adjacency. The skin fields start on the
/// superquadric itself. `extent` [m], the half sizes of the box the skin fills in the
/// superquadric's frame, sets the node counts, so nodes lie about `spacing` apart on the
/// skin even where it is far from a small superquadric.
SkinDistanceMap MakeMapGrid(const Superquadric& sq, const Eigen::Vector3d& extent,
                            double spacing);

/// Redraws the map of `segment` from its skin's corners in the superquadric frame
/// (skin.local): rays stop at their first exit from the skin, or at the segment's reach.
/// Then sets the shell's box and bounding radius for `thickness` [m].
void DrawMap(SuperquadricSegment& segment, double thickness);

/// Packs the map of `segment` as just drawn (SegmentSkin's drawing fields) into `nodes`,
/// one per grid point of each face in turn (SkinDistanceMap::face_offset), and points the
/// segment's queries at them.
void PackDrawing(SuperquadricSegment& segment, StoredMapNode* nodes);

/// The record of the drawing `segment` reads, for storing it.
void RecordDrawing(const SuperquadricSegment& segment, StoredMapDrawing& stored);

/// Points the queries of `segment` at a stored drawing of its current skin, and sets the
/// shell's box and bounding radius for `thickness` [m]: a drawing holds the skin, so it
/// serves any thickness.
void UseDrawing(const StoredMapDrawing& stored, const StoredMapNode* nodes,
                SuperquadricSegment& segment, double thickness);

/// Allocates the scratch a drawing of the segment's map works in, once, so that drawing
/// never allocates.
void AllocateDrawingScratch(SuperquadricSegment& segment);

}  // namespace costume::sim
