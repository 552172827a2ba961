#pragma once
/// @file
/// MakeHuman's avatar triple: the base mesh (base.obj), a skeleton (.mhskel, JSON) whose
/// joints are defined by base-mesh vertices, and skin weights (.mhw, JSON) indexed by
/// base-mesh vertex. assimp reads none of the JSON files and reorders OBJ vertices, so the
/// OBJ is read here too, keeping the file's vertex order.

#include <memory>
#include <string>
#include <vector>

#include "sim_core/avatar/avatar.h"
#include "sim_core/cloth/mesh_cloth.h"
#include "sim_core/scene/scene_description.h"

namespace costume::assets {

struct MakeHumanImportOptions {
  /// Metres per file unit, finite and > 0: MakeHuman's files are in decimetres.
  double scale = 0.1;
  /// The OBJ groups ("g" lines) whose faces make the avatar's surface; empty: all faces.
  /// base.obj's "body" is the closed skin; its helper-* and joint-* groups are fitting aids.
  std::vector<std::string> groups = {"body"};
  /// The avatar's name.
  std::string name = "makehuman";
};

/// The vertices of an OBJ file in file order (n×3, file units), and its faces by group.
struct ObjMesh {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> vertices;
  /// Faces as 0-based vertex indices (any number of corners ≥ 3), and each face's group.
  std::vector<std::vector<int>> faces;
  std::vector<std::string> face_groups;
};

/// Reads the `v`, `g` and `f` lines of an OBJ file (others are skipped; negative indices
/// count from the end). Throws sim::InputError naming `path` and the line for a malformed
/// number, a face index out of range, a face of fewer than 3 corners, no vertices.
ObjMesh ReadObj(const std::string& path);

/// The skeleton of a .mhskel file on the mesh `obj` (whose vertex positions define the
/// joints): one sim::Joint per bone at the bone's head, y axis towards its tail, x axis
/// from the bone's rotation plane (MakeHuman's own convention), positions × `scale`.
/// Joints mapped onto H-Anim. Throws sim::InputError naming `path` and the bone or joint
/// for: malformed JSON, a missing field, an unknown parent or a cycle, a vertex index
/// outside the mesh, a bone of zero length.
std::shared_ptr<const sim::Skeleton> LoadMakeHumanSkeleton(const std::string& path,
                                                           const ObjMesh& obj, double scale);

/// The avatar of `obj_path` + `skeleton_path` + `weights_path`: surface = the faces of
/// options.groups (quads split into two triangles), vertices kept in file order minus
/// those in no kept face, in metres; skin from the .mhw weights (4 largest per vertex,
/// renormalised; a vertex with none follows the root). Throws sim::InputError naming the
/// offending file and field.
std::shared_ptr<const sim::Avatar> LoadMakeHumanAvatar(const std::string& obj_path,
                                                       const std::string& skeleton_path,
                                                       const std::string& weights_path,
                                                       const MakeHumanImportOptions& options = {});

/// A MakeHuman garment fitted to the body `body` (base.obj with its helper groups, as
/// ReadObj gives it) the way MakeHuman fits it: each garment vertex is the weighted sum of
/// three body vertices (mostly of the helper-tights and helper-skirt surfaces, which lie
/// over the skin) plus an offset scaled per axis by the body's size (the x/y/z_scale lines:
/// the distance between two body vertices over the distance they had when the garment was
/// made). The garment's own OBJ (its `obj_file` line, beside the .mhclo) gives the faces;
/// its vertex positions are the garment's authoring shape, not fitted to base.obj (for
/// female_casualsuit02 they sit 4 cm lower, up to 5 cm inside the skin). Vertices and
/// faces keep the OBJ's order; positions × `scale` [m per file unit] (MakeHuman: 0.1).
/// Throws sim::InputError naming the .mhclo and line (or the OBJ) for: a missing or
/// malformed scale line, a row of other than 1 or 9 numbers, a body vertex index out of
/// range, a zero reference distance, a row count other than the OBJ's vertex count, and
/// what ReadObj refuses.
sim::SurfaceMesh LoadMakeHumanGarment(const std::string& mhclo_path, const ObjMesh& body,
                                      double scale = 0.1);

/// The garment OBJ a .mhclo names on its `obj_file` line, as written there (MakeHuman's
/// files name a plain file beside the .mhclo). Throws sim::InputError naming the .mhclo
/// when it cannot be read or has no such line.
std::string MakeHumanGarmentObjFile(const std::string& mhclo_path);

/// Open boundary loops within this of the waist (the vl5 joint's height at rest) are a
/// MakeHuman garment's waistband [m]: the shorts' and trousers' tops on MakeHuman's body.
inline constexpr double kMakeHumanWaistband = 0.08;
/// MakeHuman garments' rolled hems are strips of 0.5 mm edges and the fit leaves slivers:
/// edges shorter than this are welded [m], or their particles of a few milligrams would need
/// a step of 2 ms.
inline constexpr double kMakeHumanGarmentWeld = 0.005;

/// A MakeHuman garment ready to simulate, as the catalogue and collision_bench use it:
/// fitted to `body` (LoadMakeHumanGarment, MakeHuman's scale), welded below
/// kMakeHumanGarmentWeld, its waistband at `skeleton`'s vl5 (MakeHuman's skeleton on that
/// body, in metres) pinned and held by the pelvis (sacroiliac), and moved out of the
/// avatar's skin when the cloth is built (fit_outside_body). A garment with no open loop at
/// the waist (a dress worn from the shoulders) gets no pins. Name and material are left for
/// the caller. Throws sim::InputError for what LoadMakeHumanGarment refuses and for a
/// skeleton without vl5.
sim::GarmentSpec MakeHumanGarmentSpec(const std::string& mhclo_path, const ObjMesh& body,
                                      const sim::Skeleton& skeleton);

}  // namespace costume::assets
