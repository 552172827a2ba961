#include "frontend/cloth_frame_assembler.h"

namespace costume::frontend {
namespace {

/// A chunk whose header describes a possible piece of a possible frame.
bool ValidChunk(const costume_lcm::cloth_frame& c) {
  if (c.num_chunks < 1 || c.chunk_index < 0 || c.chunk_index >= c.num_chunks) return false;
  if (c.total_particles < 0 || c.first_particle < 0 || c.num_particles < 0) return false;
  if (c.num_particles > costume_lcm::cloth_frame::MAX_PARTICLES_PER_CHUNK) return false;
  if (static_cast<std::int64_t>(c.first_particle) + c.num_particles > c.total_particles) {
    return false;
  }
  const auto n = static_cast<std::size_t>(c.num_particles);
  return c.x.size() == n && c.y.size() == n && c.z.size() == n;
}

}  // namespace

bool ClothFrameAssembler::Consistent(const costume_lcm::cloth_frame& c) const {
  return c.num_chunks == header_.num_chunks && c.total_particles == header_.total_particles &&
         c.model_revision == header_.model_revision && c.mode == header_.mode;
}

void ClothFrameAssembler::Start(const costume_lcm::cloth_frame& chunk) {
  if (assembling_) ++counts_.incomplete;
  assembling_ = true;
  header_ = chunk;
  current_.frame = chunk.frame;
  current_.sim_time = chunk.sim_time;
  current_.model_revision = chunk.model_revision;
  current_.editing = chunk.mode == costume_lcm::cloth_frame::MODE_EDITING;
  current_.positions.assign(static_cast<std::size_t>(chunk.total_particles),
                            Eigen::Vector3f::Zero());
  have_chunk_.assign(static_cast<std::size_t>(chunk.num_chunks), 0);
  chunks_received_ = 0;
}

std::optional<ClothFrame> ClothFrameAssembler::Add(const costume_lcm::cloth_frame& chunk) {
  if (!ValidChunk(chunk)) {
    ++counts_.invalid;
    return std::nullopt;
  }
  if (assembling_ && chunk.frame < header_.frame) {
    ++counts_.old;
    return std::nullopt;
  }
  if (!assembling_ || chunk.frame > header_.frame) Start(chunk);
  if (!Consistent(chunk)) {
    ++counts_.invalid;
    return std::nullopt;
  }
  const auto index = static_cast<std::size_t>(chunk.chunk_index);
  if (have_chunk_[index]) return std::nullopt;  // a repeat: already have it
  have_chunk_[index] = 1;
  for (int i = 0; i < chunk.num_particles; ++i) {
    current_.positions[static_cast<std::size_t>(chunk.first_particle + i)] =
        Eigen::Vector3f(chunk.x[i], chunk.y[i], chunk.z[i]);
  }
  if (++chunks_received_ < chunk.num_chunks) return std::nullopt;
  assembling_ = false;
  ++counts_.frames;
  return std::move(current_);
}

}  // namespace costume::frontend
