#include "frontend/cloth_frame_assembler.h"

#include <gtest/gtest.h>

namespace costume::frontend {
namespace {

/// Chunk `index` of frame `frame` holding particles [first, first + n) of `total`, particle
/// i at (i, 2i, -i).
costume_lcm::cloth_frame Chunk(std::int64_t frame, int index, int chunks, int first, int n,
                               int total) {
  costume_lcm::cloth_frame c{};
  c.frame = frame;
  c.sim_time = frame / 60.0;
  c.chunk_index = static_cast<std::int16_t>(index);
  c.num_chunks = static_cast<std::int16_t>(chunks);
  c.first_particle = first;
  c.num_particles = static_cast<std::int16_t>(n);
  c.total_particles = total;
  c.mode = costume_lcm::cloth_frame::MODE_EDITING;
  for (int i = first; i < first + n; ++i) {
    c.x.push_back(static_cast<float>(i));
    c.y.push_back(static_cast<float>(2 * i));
    c.z.push_back(static_cast<float>(-i));
  }
  return c;
}

void ExpectParticles(const ClothFrame& frame, int total) {
  ASSERT_EQ(static_cast<int>(frame.positions.size()), total);
  for (int i = 0; i < total; ++i) {
    EXPECT_EQ(frame.positions[i], Eigen::Vector3f(i, 2 * i, -i)) << i;
  }
}

TEST(ClothFrameAssembler, OneChunkIsAWholeFrame) {
  ClothFrameAssembler assembler;
  const auto frame = assembler.Add(Chunk(7, 0, 1, 0, 10, 10));
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->frame, 7);
  EXPECT_DOUBLE_EQ(frame->sim_time, 7 / 60.0);
  EXPECT_TRUE(frame->editing);
  ExpectParticles(*frame, 10);
}

TEST(ClothFrameAssembler, ChunksInAnyOrderMakeOneFrame) {
  ClothFrameAssembler assembler;
  EXPECT_FALSE(assembler.Add(Chunk(3, 2, 3, 8, 2, 10)));
  EXPECT_FALSE(assembler.Add(Chunk(3, 0, 3, 0, 4, 10)));
  EXPECT_FALSE(assembler.Add(Chunk(3, 0, 3, 0, 4, 10)));  // a repeat changes nothing
  const auto frame = assembler.Add(Chunk(3, 1, 3, 4, 4, 10));
  ASSERT_TRUE(frame);
  ExpectParticles(*frame, 10);
  EXPECT_EQ(assembler.counts().frames, 1);
}

TEST(ClothFrameAssembler, ALostChunkAbandonsItsFrame) {
  ClothFrameAssembler assembler;
  EXPECT_FALSE(assembler.Add(Chunk(3, 0, 2, 0, 5, 10)));  // chunk 1 of frame 3 never comes
  EXPECT_FALSE(assembler.Add(Chunk(4, 0, 2, 0, 5, 10)));
  EXPECT_FALSE(assembler.Add(Chunk(3, 1, 2, 5, 5, 10)));  // late: older than frame 4
  const auto frame = assembler.Add(Chunk(4, 1, 2, 5, 5, 10));
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->frame, 4);
  EXPECT_EQ(assembler.counts().incomplete, 1);
  EXPECT_EQ(assembler.counts().old, 1);
}

TEST(ClothFrameAssembler, RepeatedAndRestartedFramesAreShown) {
  ClothFrameAssembler assembler;
  ASSERT_TRUE(assembler.Add(Chunk(9, 0, 1, 0, 3, 3)));
  EXPECT_TRUE(assembler.Add(Chunk(9, 0, 1, 0, 3, 3)));  // paused: the same frame again
  EXPECT_TRUE(assembler.Add(Chunk(0, 0, 1, 0, 3, 3)));  // STOP rebuilt the scene
}

TEST(ClothFrameAssembler, RefusesChunksThatDoNotFit) {
  ClothFrameAssembler assembler;
  EXPECT_FALSE(assembler.Add(Chunk(1, 1, 1, 0, 3, 3)));   // index outside [0, num_chunks)
  EXPECT_FALSE(assembler.Add(Chunk(1, 0, 1, 2, 3, 3)));   // particles past the total
  auto short_arrays = Chunk(1, 0, 1, 0, 3, 3);
  short_arrays.z.pop_back();
  EXPECT_FALSE(assembler.Add(short_arrays));
  EXPECT_EQ(assembler.counts().invalid, 3);
  EXPECT_FALSE(assembler.Add(Chunk(2, 0, 2, 0, 3, 6)));
  EXPECT_FALSE(assembler.Add(Chunk(2, 1, 3, 3, 3, 6)));   // disagrees with chunk 0's header
  EXPECT_EQ(assembler.counts().invalid, 4);
}

}  // namespace
}  // namespace costume::frontend
