// The thread pool does every index once, its chunked sums and the solver's loops give the same
// bits with any thread count, and the PCG solve on it equals the solve on one thread to the bit
// and the dense solution to its tolerance.

#include "sim_core/common/thread_pool.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <atomic>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "sim_core/common/input_error.h"
#include "sim_core/solver/filtered_pcg.h"
#include "sim_core/solver/system_matrix.h"
#include "tests/support/count_mallocs.h"

namespace costume::sim {
namespace {

TEST(ThreadPool, CallsEveryIndexExactlyOnceLoopAfterLoop) {
  ThreadPool pool(2);
  for (int count : {1, 2, 3, 17, 1000}) {
    std::vector<std::atomic<int>> calls(count);
    for (int loop = 0; loop < 50; ++loop) pool.ForEach(count, [&](int i) { calls[i]++; });
    for (int i = 0; i < count; ++i) EXPECT_EQ(calls[i].load(), 50) << "index " << i;
  }
}

TEST(ThreadPool, ChunksCoverTheParticlesInFixedPieces) {
  const int n = 3 * ThreadPool::kChunkParticles + 5;
  EXPECT_EQ(ThreadPool::NumChunks(n), 4);
  std::vector<int> owner(n, -1);
  ThreadPool pool(3);
  pool.ForEachChunk(n, [&](int begin, int end) {
    EXPECT_EQ(begin % ThreadPool::kChunkParticles, 0);
    for (int i = begin; i < end; ++i) owner[i] = begin;
  });
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(owner[i], i / ThreadPool::kChunkParticles * ThreadPool::kChunkParticles);
  }
}

TEST(ThreadPool, RefusesAThreadCountOutOfRange) {
  EXPECT_THROW(ThreadPool(0), InputError);
  EXPECT_THROW(ThreadPool(ThreadPool::kMaxThreads + 1), InputError);
}

TEST(ThreadPool, ChunkedSumIsTheSameBitsWithAnyThreadCount) {
  // Values of very different magnitude: a different order of addition changes the bits.
  const int n = 5000;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> exponent(-12.0, 12.0);
  std::vector<double> v(n);
  for (double& x : v) x = std::pow(10.0, exponent(rng)) * (rng() % 2 ? 1.0 : -1.0);
  std::vector<double> partial(ThreadPool::NumChunks(n));
  const auto sum = [&](ThreadPool* pool) {
    return SumOverParticleChunks(pool, n, partial, [&](int begin, int end) {
      double s = 0.0;
      for (int i = begin; i < end; ++i) s += v[i];
      return s;
    });
  };
  const double alone = sum(nullptr);
  for (int threads : {1, 2, 3, 5}) {
    ThreadPool pool(threads);
    for (int repeat = 0; repeat < 20; ++repeat) EXPECT_EQ(sum(&pool), alone) << threads;
  }
}

/// A random SPD block system over a ring of particles with chords: A = M + Σ couplings of
/// positive semi-definite blocks.
SystemMatrix RandomSpdSystem(int n, std::mt19937& rng) {
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < n; ++i) {
    pairs.emplace_back(i, (i + 1) % n);
    pairs.emplace_back(i, (i + 37) % n);
  }
  SystemMatrix a(n, pairs);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < n; ++i) a.AddToDiagonal(i, 1e-3 * Eigen::Matrix3d::Identity());
  for (int s = 0; s < static_cast<int>(pairs.size()); ++s) {
    const Eigen::Vector3d d = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    a.AddSpringCoupling(s, 0.01, 1.0 + u(rng), d);  // 0.01 I + (1 ± 1) d dᵀ: PSD
  }
  return a;
}

TEST(ThreadPool, PcgOnTwoThreadsEqualsOneToTheBitAndTheDenseSolution) {
  const int n = 700;  // three chunks; small enough for the dense check
  std::mt19937 rng(11);
  const SystemMatrix a = RandomSpdSystem(n, rng);
  const Eigen::VectorXd b = Eigen::VectorXd::Random(3 * n);
  Constraints constraints(n);
  PcgSettings settings;
  settings.tolerance = 1e-8;
  settings.max_iterations = 5000;
  const auto solve = [&](ThreadPool* pool) {
    settings.pool = pool;
    BlockJacobiPreconditioner jacobi(n, pool);
    jacobi.Update(a, constraints);
    FilteredPcg pcg(n);
    Eigen::VectorXd dv = Eigen::VectorXd::Zero(3 * n);
    const PcgReport report = pcg.Solve(a, b, constraints, settings, jacobi, dv);
    EXPECT_TRUE(report.converged);
    return dv;
  };
  const Eigen::VectorXd alone = solve(nullptr);
  ThreadPool pool(2);
  const Eigen::VectorXd two = solve(&pool);
  EXPECT_EQ(std::memcmp(alone.data(), two.data(), sizeof(double) * alone.size()), 0);

  // Independently: the dense matrix of the same additions, solved by LDLᵀ.
  Eigen::MatrixXd dense(3 * n, 3 * n);
  for (int j = 0; j < 3 * n; ++j) {
    Eigen::VectorXd e = Eigen::VectorXd::Unit(3 * n, j), column(3 * n);
    a.Multiply(e, column);
    dense.col(j) = column;
  }
  const Eigen::VectorXd exact = dense.ldlt().solve(b);
  EXPECT_LT((two - exact).norm(), 1e-5 * exact.norm());
}

TEST(ThreadPool, ASolveOnTwoThreadsAllocatesNothingAfterTheFirst) {
  const int n = 1500;
  std::mt19937 rng(5);
  const SystemMatrix a = RandomSpdSystem(n, rng);
  const Eigen::VectorXd b = Eigen::VectorXd::Random(3 * n);
  Constraints constraints(n);
  ThreadPool pool(2);
  PcgSettings settings;
  settings.tolerance = 1e-6;
  settings.pool = &pool;
  BlockJacobiPreconditioner jacobi(n, &pool);
  FilteredPcg pcg(n);
  Eigen::VectorXd dv = Eigen::VectorXd::Zero(3 * n);
  jacobi.Update(a, constraints);
  pcg.Solve(a, b, constraints, settings, jacobi, dv);
  dv.setZero();
  g_num_allocations = 0;
  g_count_allocations = true;
  jacobi.Update(a, constraints);
  const PcgReport report = pcg.Solve(a, b, constraints, settings, jacobi, dv);
  g_count_allocations = false;
  EXPECT_GT(report.iterations, 10);
  EXPECT_EQ(g_num_allocations, 0);
}

}  // namespace
}  // namespace costume::sim
