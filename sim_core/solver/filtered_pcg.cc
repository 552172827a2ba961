#include "sim_core/solver/filtered_pcg.h"

#include <Eigen/LU>
#include <cmath>

namespace costume::sim {

// Constrained particles get the inverse of their filtered block, S(SDS + I − S)⁻¹S, not
// S D⁻¹ S: where D couples the contact normal to the tangent plane the latter can exceed the
// true inverse, and a multigrid smoother built on it then amplifies instead of smoothing.
void BlockJacobiPreconditioner::Update(const SystemMatrix& a, const Constraints& constraints) {
  ForEachParticleChunk(pool_, a.num_particles(), [&](int begin, int end) {
    for (int i = begin; i < end; ++i) inverse_diagonal_[i] = a.DiagonalBlock(i).inverse();
  });
  for (int i : constraints.constrained()) {
    if (constraints.num_constrained_directions(i) == 3) {
      inverse_diagonal_[i].setZero();
      continue;
    }
    const Eigen::Vector3d& n = constraints.normal(i);
    const Eigen::Matrix3d normal = n * n.transpose();
    const Eigen::Matrix3d s = Eigen::Matrix3d::Identity() - normal;
    inverse_diagonal_[i] = s * (s * a.DiagonalBlock(i) * s + normal).inverse() * s;
  }
}

void BlockJacobiPreconditioner::Apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) {
  ForEachParticleChunk(pool_, static_cast<int>(inverse_diagonal_.size()), [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      z.segment<3>(3 * i).noalias() = inverse_diagonal_[i] * r.segment<3>(3 * i);
    }
  });
}

double ChunkedDot(ThreadPool* pool, const Eigen::VectorXd& x, const Eigen::VectorXd& y,
                  std::vector<double>& partial) {
  return SumOverParticleChunks(pool, static_cast<int>(x.size() / 3), partial,
                               [&](int begin, int end) {
                                 const int length = 3 * (end - begin);
                                 return x.segment(3 * begin, length).dot(y.segment(3 * begin, length));
                               });
}

FilteredPcg::FilteredPcg(int num_particles)
    : r_(3 * num_particles),
      c_(3 * num_particles),
      q_(3 * num_particles),
      s_(3 * num_particles),
      partial_(ThreadPool::NumChunks(num_particles)) {}

PcgReport FilteredPcg::Solve(const SystemMatrix& a, const Eigen::VectorXd& b,
                             const Constraints& constraints, const PcgSettings& settings,
                             PcgPreconditioner& preconditioner, Eigen::VectorXd& dv) {
  PcgReport report;
  // Start from the guess with its constrained components replaced by the prescribed ones.
  constraints.Filter(dv);
  dv += constraints.prescribed();

  // Two stopping tests, both relative to the right-hand side: the plain residual ‖S(b − AΔv)‖
  // (a force balance) and B&W's preconditioned one rᵀP⁻¹r. With block Jacobi, rᵀP⁻¹r weighs
  // each particle by the inverse of its stiff diagonal and calls smooth, large-scale errors
  // converged; with a multigrid P it approximates the energy norm of the error, which the
  // plain residual underrates in soft modes. Either alone at a loose tolerance let energy
  // into stiff cloth (stability_matrix_test); both together hold for every preconditioner.
  ThreadPool* pool = settings.pool;
  const int n = a.num_particles();
  const auto dot = [&](const Eigen::VectorXd& x, const Eigen::VectorXd& y) {
    return ChunkedDot(pool, x, y, partial_);
  };
  r_ = b;
  constraints.Filter(r_);
  const double reference = dot(r_, r_);
  preconditioner.Apply(r_, s_);
  constraints.Filter(s_);
  const double reference_preconditioned = dot(r_, s_);

  a.Multiply(dv, q_, pool);
  r_ = b - q_;
  constraints.Filter(r_);
  preconditioner.Apply(r_, c_);
  constraints.Filter(c_);
  double delta = dot(r_, c_);
  double residual = dot(r_, r_);
  const double tolerance2 = settings.tolerance * settings.tolerance;
  const auto converged = [&] {
    return residual <= tolerance2 * reference && delta <= tolerance2 * reference_preconditioned;
  };
  while (!converged() && report.iterations < settings.max_iterations) {
    a.Multiply(c_, q_, pool);
    constraints.Filter(q_);
    const double curvature = dot(c_, q_);
    if (!(curvature > 0.0)) break;  // not positive definite on this subspace: stop safely
    const double alpha = delta / curvature;
    // dv += αc and r −= αq with r·r, in one pass over the vectors.
    residual = SumOverParticleChunks(pool, n, partial_, [&](int begin, int end) {
      const int at = 3 * begin, length = 3 * (end - begin);
      dv.segment(at, length).noalias() += alpha * c_.segment(at, length);
      r_.segment(at, length).noalias() -= alpha * q_.segment(at, length);
      return r_.segment(at, length).squaredNorm();
    });
    preconditioner.Apply(r_, s_);
    constraints.Filter(s_);
    const double delta_old = delta;
    delta = dot(r_, s_);
    const double beta = delta / delta_old;
    ForEachParticleChunk(pool, n, [&](int begin, int end) {  // both terms filtered already
      const int at = 3 * begin, length = 3 * (end - begin);
      c_.segment(at, length) = s_.segment(at, length) + beta * c_.segment(at, length);
    });
    ++report.iterations;
  }
  report.converged = converged();
  report.relative_residual = reference > 0.0 ? std::sqrt(residual / reference) : 0.0;
  return report;
}

}  // namespace costume::sim
