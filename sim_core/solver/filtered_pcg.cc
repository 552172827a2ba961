#include "sim_core/solver/filtered_pcg.h"

#include <Eigen/LU>
#include <cmath>

namespace costume::sim {

// Constrained particles get the inverse of their filtered block, S(SDS + I − S)⁻¹S, not
// S D⁻¹ S: where D couples the contact normal to the tangent plane the latter can exceed the
// true inverse, and a multigrid smoother built on it then amplifies instead of smoothing.
void BlockJacobiPreconditioner::Update(const SystemMatrix& a, const Constraints& constraints) {
  for (int i = 0; i < a.num_particles(); ++i) {
    inverse_diagonal_[i] = a.DiagonalBlock(i).inverse();
  }
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
  for (std::size_t i = 0; i < inverse_diagonal_.size(); ++i) {
    z.segment<3>(3 * i).noalias() = inverse_diagonal_[i] * r.segment<3>(3 * i);
  }
}

FilteredPcg::FilteredPcg(int num_particles)
    : r_(3 * num_particles), c_(3 * num_particles), q_(3 * num_particles), s_(3 * num_particles) {}

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
  r_ = b;
  constraints.Filter(r_);
  const double reference = r_.squaredNorm();
  preconditioner.Apply(r_, s_);
  constraints.Filter(s_);
  const double reference_preconditioned = r_.dot(s_);

  a.Multiply(dv, q_);
  r_ = b - q_;
  constraints.Filter(r_);
  preconditioner.Apply(r_, c_);
  constraints.Filter(c_);
  double delta = r_.dot(c_);
  double residual = r_.squaredNorm();
  const double tolerance2 = settings.tolerance * settings.tolerance;
  const auto converged = [&] {
    return residual <= tolerance2 * reference && delta <= tolerance2 * reference_preconditioned;
  };
  while (!converged() && report.iterations < settings.max_iterations) {
    a.Multiply(c_, q_);
    constraints.Filter(q_);
    const double curvature = c_.dot(q_);
    if (!(curvature > 0.0)) break;  // not positive definite on this subspace: stop safely
    const double alpha = delta / curvature;
    dv.noalias() += alpha * c_;
    r_.noalias() -= alpha * q_;
    residual = r_.squaredNorm();
    preconditioner.Apply(r_, s_);
    constraints.Filter(s_);
    const double delta_old = delta;
    delta = r_.dot(s_);
    c_ = s_ + (delta / delta_old) * c_;  // both terms filtered already
    ++report.iterations;
  }
  report.converged = converged();
  report.relative_residual = reference > 0.0 ? std::sqrt(residual / reference) : 0.0;
  return report;
}

}  // namespace costume::sim
