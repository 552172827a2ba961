#include "sim_core/solver/system_matrix.h"

#include <algorithm>
#include <utility>

namespace costume::sim {

namespace {

/// The index in a coupling block's six values (xx, xy, xz, yy, yz, zz) of each of the nine
/// row-major entries of a 3×3 block.
constexpr int kUpper[9] = {0, 1, 2, 1, 3, 4, 2, 4, 5};

/// identity·I + along·u uᵀ as a coupling block's six values.
void ClosedFormBlock(double identity, double along, const Eigen::Vector3d& u, double* block) {
  block[0] = identity + along * u[0] * u[0];
  block[1] = along * u[0] * u[1];
  block[2] = along * u[0] * u[2];
  block[3] = identity + along * u[1] * u[1];
  block[4] = along * u[1] * u[2];
  block[5] = identity + along * u[2] * u[2];
}

}  // namespace

SystemMatrix::SystemMatrix(const ClothModel& model)
    : num_particles_(model.num_particles()),
      diagonal_(9 * static_cast<std::size_t>(model.num_particles()), 0.0),
      coupling_(6 * model.springs().size(), 0.0) {
  spring_ends_.reserve(model.springs().size());
  for (const Spring& s : model.springs()) spring_ends_.emplace_back(s.a, s.b);
  BuildRowIndex();
}

SystemMatrix::SystemMatrix(int num_particles, std::vector<std::pair<int, int>> pairs)
    : num_particles_(num_particles),
      diagonal_(9 * static_cast<std::size_t>(num_particles), 0.0),
      coupling_(6 * pairs.size(), 0.0),
      spring_ends_(std::move(pairs)) {
  BuildRowIndex();
}

void SystemMatrix::BuildRowIndex() {
  row_start_.assign(num_particles_ + 1, 0);
  for (const auto& [a, b] : spring_ends_) {
    ++row_start_[a + 1];
    ++row_start_[b + 1];
  }
  for (int i = 0; i < num_particles_; ++i) row_start_[i + 1] += row_start_[i];
  row_entries_.resize(2 * spring_ends_.size());
  std::vector<int> next(row_start_.begin(), row_start_.end() - 1);
  for (int s = 0; s < num_springs(); ++s) {
    const auto [a, b] = spring_ends_[s];
    row_entries_[next[a]++] = {b, s};
    row_entries_[next[b]++] = {a, s};
  }
}

void SystemMatrix::SetZero() {
  std::fill(diagonal_.begin(), diagonal_.end(), 0.0);
  std::fill(coupling_.begin(), coupling_.end(), 0.0);
}

void SystemMatrix::AddToDiagonal(int i, const Eigen::Matrix3d& block) {
  double* d = &diagonal_[9 * static_cast<std::size_t>(i)];
  for (int e = 0; e < 9; ++e) d[e] += block(e / 3, e % 3);
}

void SystemMatrix::AddSpringCoupling(int spring, const Eigen::Matrix3d& block) {
  const auto [a, b] = spring_ends_[spring];
  AddToDiagonal(a, block);
  AddToDiagonal(b, block);
  double* c = &coupling_[6 * static_cast<std::size_t>(spring)];
  c[0] += block(0, 0);
  c[1] += block(0, 1);
  c[2] += block(0, 2);
  c[3] += block(1, 1);
  c[4] += block(1, 2);
  c[5] += block(2, 2);
}

void SystemMatrix::AddSpringCoupling(int spring, double identity, double along,
                                     const Eigen::Vector3d& u) {
  double block[6];
  ClosedFormBlock(identity, along, u, block);
  const auto [a, b] = spring_ends_[spring];
  double* c = &coupling_[6 * static_cast<std::size_t>(spring)];
  for (int e = 0; e < 6; ++e) c[e] += block[e];
  double* da = &diagonal_[9 * static_cast<std::size_t>(a)];
  double* db = &diagonal_[9 * static_cast<std::size_t>(b)];
  for (int e = 0; e < 9; ++e) {
    da[e] += block[kUpper[e]];
    db[e] += block[kUpper[e]];
  }
}

void SystemMatrix::SetSpringCoupling(int spring, double identity, double along,
                                     const Eigen::Vector3d& u) {
  ClosedFormBlock(identity, along, u, &coupling_[6 * static_cast<std::size_t>(spring)]);
}

void SystemMatrix::AddCouplingsToDiagonals(int begin, int end) {
  for (int i = begin; i < end; ++i) {
    double* d = &diagonal_[9 * static_cast<std::size_t>(i)];
    for (int k = row_start_[i]; k < row_start_[i + 1]; ++k) {
      const double* c = &coupling_[6 * static_cast<std::size_t>(row_entries_[k].second)];
      for (int e = 0; e < 9; ++e) d[e] += c[kUpper[e]];
    }
  }
}

void SystemMatrix::AddSpringVectors(int begin, int end, const Eigen::VectorXd& v,
                                    Eigen::VectorXd& out) const {
  for (int i = begin; i < end; ++i) {
    for (int k = row_start_[i]; k < row_start_[i + 1]; ++k) {
      const int s = row_entries_[k].second;
      if (spring_ends_[s].first == i) {
        out.segment<3>(3 * i) += v.segment<3>(3 * s);
      } else {
        out.segment<3>(3 * i) -= v.segment<3>(3 * s);
      }
    }
  }
}

void SystemMatrix::Multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, ThreadPool* pool) const {
  ForEachParticleChunk(pool, num_particles_,
                       [&](int begin, int end) { MultiplyRows(begin, end, x, y); });
}

void SystemMatrix::MultiplyRows(int begin, int end, const Eigen::VectorXd& x,
                                Eigen::VectorXd& y) const {
  const double* xs = x.data();
  double* ys = y.data();
  const double* d = diagonal_.data() + 9 * static_cast<std::size_t>(begin);
  const double* coupling = coupling_.data();
  const std::pair<int, int>* entry = row_entries_.data() + row_start_[begin];
  for (int i = begin; i < end; ++i, d += 9) {
    const double* xi = xs + 3 * i;
    double y0 = d[0] * xi[0] + d[1] * xi[1] + d[2] * xi[2];
    double y1 = d[3] * xi[0] + d[4] * xi[1] + d[5] * xi[2];
    double y2 = d[6] * xi[0] + d[7] * xi[1] + d[8] * xi[2];
    for (const std::pair<int, int>* last = row_entries_.data() + row_start_[i + 1]; entry != last;
         ++entry) {
      const double* xj = xs + 3 * entry->first;
      const double* c = coupling + 6 * static_cast<std::size_t>(entry->second);
      y0 -= c[0] * xj[0] + c[1] * xj[1] + c[2] * xj[2];
      y1 -= c[1] * xj[0] + c[3] * xj[1] + c[4] * xj[2];
      y2 -= c[2] * xj[0] + c[4] * xj[1] + c[5] * xj[2];
    }
    ys[3 * i] = y0;
    ys[3 * i + 1] = y1;
    ys[3 * i + 2] = y2;
  }
}

Eigen::Matrix3d SystemMatrix::DiagonalBlock(int i) const {
  return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(
      &diagonal_[9 * static_cast<std::size_t>(i)]);
}

Eigen::Matrix3d SystemMatrix::SpringBlock(int spring) const {
  const double* c = &coupling_[6 * static_cast<std::size_t>(spring)];
  Eigen::Matrix3d block;
  block << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
  return block;
}

}  // namespace costume::sim
