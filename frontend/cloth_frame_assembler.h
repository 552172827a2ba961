#pragma once
/// @file
/// Reassembles the chunks of a cloth frame (lcm_types/cloth_frame.lcm): a frame of more than
/// 5,000 particles arrives as num_chunks messages sharing `frame`. The GUI shows whole frames
/// only; a frame with a lost chunk is abandoned when a chunk of a newer frame arrives.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "lcm_types/costume_lcm/cloth_frame.hpp"

namespace costume::frontend {

/// One whole simulated frame as the GUI uses it.
struct ClothFrame {
  std::int64_t frame = -1;         ///< cloth_frame.frame
  double sim_time = 0.0;           ///< simulated time since scene load [s]
  std::int64_t model_revision = 0;
  bool editing = false;            ///< mode B (MODE_EDITING)
  std::vector<Eigen::Vector3f> positions;  ///< every particle, scene frame [m]
};

/// What happened to chunks so far.
struct AssemblyCounts {
  std::int64_t frames = 0;       ///< whole frames returned
  std::int64_t incomplete = 0;   ///< frames abandoned with chunks missing
  std::int64_t invalid = 0;      ///< chunks refused: bad header, ranges outside the frame,
                                 ///< or a header disagreeing with the frame's first chunk
  std::int64_t old = 0;          ///< chunks of a frame older than the one being assembled
};

/// Collects chunks one frame at a time. Chunks may come in any order within a frame.
class ClothFrameAssembler {
 public:
  /// Takes one chunk; returns the frame when this chunk completed it. While a frame is being
  /// assembled, a chunk of a newer frame abandons it (counted incomplete) and a chunk of an
  /// older one is ignored (counted old); a repeated chunk is ignored. Between frames any
  /// frame number starts a new assembly: a paused server republishes the same frame, and a
  /// rebuilt scene (STOP, SET_SOLVER) starts again at frame 0.
  std::optional<ClothFrame> Add(const costume_lcm::cloth_frame& chunk);

  const AssemblyCounts& counts() const { return counts_; }

 private:
  bool Consistent(const costume_lcm::cloth_frame& chunk) const;
  void Start(const costume_lcm::cloth_frame& chunk);

  bool assembling_ = false;
  costume_lcm::cloth_frame header_{};
  ClothFrame current_;
  std::vector<char> have_chunk_;
  int chunks_received_ = 0;
  AssemblyCounts counts_;
};

}  // namespace costume::frontend
