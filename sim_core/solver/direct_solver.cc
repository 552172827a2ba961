#include "sim_core/solver/direct_solver.h"

#include <Eigen/CholmodSupport>
#include <algorithm>
#include <limits>
#include <vector>

namespace costume::sim {

namespace {

/// Eigen's supernodal CHOLMOD with its factor in reach: Eigen's solve goes through
/// cholmod_solve, which allocates its result on every call (the multigrid's coarsest level
/// solves once per V-cycle); cholmod_solve2 reuses workspaces kept between calls.
class Cholesky : public Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> {
 public:
  cholmod_factor* factor() { return m_cholmodFactor; }
};

}  // namespace

struct DirectSolver::Impl {
  ~Impl() {
    cholmod_common& common = cholesky.cholmod();
    cholmod_free_dense(&x, &common);
    cholmod_free_dense(&y_work, &common);
    cholmod_free_dense(&e_work, &common);
  }
  Cholesky cholesky;
  // cholmod_solve2's result and workspaces: allocated by its first call, reused after.
  cholmod_dense* x = nullptr;
  cholmod_dense* y_work = nullptr;
  cholmod_dense* e_work = nullptr;
  /// The filtered matrix in CHOLMOD's compressed-column form, same pattern as A.
  Eigen::SparseMatrix<double> filtered;
  /// For each scalar entry of A's blocks (ForEachEntry's slots): its index in filtered's
  /// value array.
  std::vector<int> value_index;
  Eigen::VectorXd rhs, az, y;
};

namespace {

/// The 3×3 filter S_i of particle i.
Eigen::Matrix3d FilterBlock(const Constraints& constraints, int i) {
  switch (constraints.num_constrained_directions(i)) {
    case 0: return Eigen::Matrix3d::Identity();
    case 3: return Eigen::Matrix3d::Zero();
    default: {
      const Eigen::Vector3d& n = constraints.normal(i);
      return Eigen::Matrix3d::Identity() - n * n.transpose();
    }
  }
}

/// Builds the scalar pattern of A and where each block entry lands in it.
void BuildPattern(const SystemMatrix& a, DirectSolver::Impl& m);

}  // namespace

DirectSolver::DirectSolver(const SystemMatrix& a) : impl_(std::make_unique<Impl>()) {
  BuildPattern(a, *impl_);
  impl_->cholesky.analyzePattern(impl_->filtered);
}

DirectSolver::~DirectSolver() = default;

namespace {

/// Calls visit(row, col, slot) for the nine scalar entries of every block A has: slots
/// [0, 9n) are the diagonal blocks, then 18 per spring, (a, b) before (b, a).
template <typename Visit>
void ForEachEntry(const SystemMatrix& a, Visit visit) {
  int slot = 0;
  auto block = [&](int i, int j) {
    for (int e = 0; e < 9; ++e) visit(3 * i + e / 3, 3 * j + e % 3, slot++);
  };
  for (int i = 0; i < a.num_particles(); ++i) block(i, i);
  for (int s = 0; s < a.num_springs(); ++s) {
    const auto [i, j] = a.spring_ends(s);
    block(i, j);
    block(j, i);
  }
}

void BuildPattern(const SystemMatrix& a, DirectSolver::Impl& m) {
  const int n3 = 3 * a.num_particles();
  std::vector<Eigen::Triplet<double>> triplets;
  ForEachEntry(a, [&](int row, int col, int) { triplets.emplace_back(row, col, 0.0); });
  m.filtered.resize(n3, n3);
  m.filtered.setFromTriplets(triplets.begin(), triplets.end());
  m.filtered.makeCompressed();
  m.value_index.resize(triplets.size());
  ForEachEntry(a, [&](int row, int col, int slot) {
    const int* first = m.filtered.innerIndexPtr() + m.filtered.outerIndexPtr()[col];
    const int* last = m.filtered.innerIndexPtr() + m.filtered.outerIndexPtr()[col + 1];
    m.value_index[slot] =
        static_cast<int>(std::lower_bound(first, last, row) - m.filtered.innerIndexPtr());
  });
}

/// Copies A into the CSC matrix, replacing every block touching a constrained particle by
/// S_i A_ij S_j (+ I − S_i on the diagonal): same pattern, SPD, constrained directions
/// decoupled. Springs joining the same pair share entries, so values are summed.
void CopyFiltered(const SystemMatrix& a, const Constraints& constraints,
                  DirectSolver::Impl& m) {
  double* values = m.filtered.valuePtr();
  std::fill(values, values + m.filtered.nonZeros(), 0.0);
  int slot = 0;
  auto add = [&](const Eigen::Matrix3d& block) {
    for (int e = 0; e < 9; ++e) values[m.value_index[slot++]] += block(e / 3, e % 3);
  };
  auto filtered = [&](int i, int j, const Eigen::Matrix3d& block) -> Eigen::Matrix3d {
    if (constraints.num_constrained_directions(i) == 0 &&
        constraints.num_constrained_directions(j) == 0) {
      return block;
    }
    return FilterBlock(constraints, i) * block * FilterBlock(constraints, j);
  };
  for (int i = 0; i < a.num_particles(); ++i) {
    Eigen::Matrix3d block = filtered(i, i, a.DiagonalBlock(i));
    if (constraints.num_constrained_directions(i) != 0) {
      block += Eigen::Matrix3d::Identity() - FilterBlock(constraints, i);
    }
    add(block);
  }
  for (int s = 0; s < a.num_springs(); ++s) {
    const auto [i, j] = a.spring_ends(s);
    const Eigen::Matrix3d coupling = -a.SpringBlock(s);
    add(filtered(i, j, coupling));
    add(filtered(j, i, coupling));
  }
}

}  // namespace

bool DirectSolver::Factorize(const SystemMatrix& a, const Constraints& constraints) {
  CopyFiltered(a, constraints, *impl_);
  impl_->cholesky.factorize(impl_->filtered);
  return impl_->cholesky.info() == Eigen::Success;
}

void DirectSolver::SolveFactored(const Eigen::VectorXd& rhs, Eigen::VectorXd& y) {
  Impl& m = *impl_;
  cholmod_dense b{};
  b.ncol = 1;
  b.nrow = static_cast<std::size_t>(rhs.size());
  b.nzmax = b.d = b.nrow;
  b.x = const_cast<double*>(rhs.data());  // read only
  b.xtype = CHOLMOD_REAL;
  b.dtype = CHOLMOD_DOUBLE;
  if (!cholmod_solve2(CHOLMOD_A, m.cholesky.factor(), &b, nullptr, &m.x, nullptr, &m.y_work,
                      &m.e_work, &m.cholesky.cholmod())) {
    y.setConstant(rhs.size(), std::numeric_limits<double>::quiet_NaN());  // callers test finiteness
    return;
  }
  y = Eigen::Map<const Eigen::VectorXd>(static_cast<const double*>(m.x->x), rhs.size());
}

bool DirectSolver::Solve(const SystemMatrix& a, const Eigen::VectorXd& b,
                         const Constraints& constraints, Eigen::VectorXd& dv) {
  Impl& m = *impl_;
  if (!Factorize(a, constraints)) return false;
  m.az.resize(b.size());
  a.Multiply(constraints.prescribed(), m.az);
  m.rhs = b - m.az;
  constraints.Filter(m.rhs);
  SolveFactored(m.rhs, m.y);
  if (m.cholesky.info() != Eigen::Success || !m.y.allFinite()) return false;
  dv = m.y + constraints.prescribed();
  return true;
}

}  // namespace costume::sim
