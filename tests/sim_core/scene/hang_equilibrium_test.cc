// The hanging cloth settles to the static equilibrium found independently: Newton's method
// on the potential energy, with its own force and exact Hessian written here, solved by
// CHOLMOD.
#include <gtest/gtest.h>

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>
#include <vector>

#include "sim_core/scene/simulation.h"
#include "tests/support/test_scenes.h"

namespace costume::sim {
namespace {

/// Gradient of V(x) = Σ ½k(|x_b − x_a| − L)² − Σ m g·x and its exact Hessian, on all 3n
/// coordinates. Written from the formula, not from the engine's force code.
void EnergyGradientAndHessian(const ClothModel& model, const Eigen::VectorXd& x,
                              const Eigen::Vector3d& g, Eigen::VectorXd* grad,
                              Eigen::SparseMatrix<double>* hess) {
  const int n = model.num_particles();
  *grad = Eigen::VectorXd::Zero(3 * n);
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) grad->segment<3>(3 * i) -= model.masses()[i] * g;
  for (const Spring& s : model.springs()) {
    const Eigen::Vector3d d = x.segment<3>(3 * s.b) - x.segment<3>(3 * s.a);
    const double l = d.norm();
    const Eigen::Vector3d u = d / l;
    // dV/dx_b = k (l − L) u
    const Eigen::Vector3d gb = s.stiffness * (l - s.rest_length) * u;
    grad->segment<3>(3 * s.b) += gb;
    grad->segment<3>(3 * s.a) -= gb;
    // d²V/dx_b² = k [u uᵀ + (1 − L/l)(I − u uᵀ)]
    const Eigen::Matrix3d uu = u * u.transpose();
    const Eigen::Matrix3d h =
        s.stiffness * (uu + (1 - s.rest_length / l) * (Eigen::Matrix3d::Identity() - uu));
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        t.emplace_back(3 * s.a + r, 3 * s.a + c, h(r, c));
        t.emplace_back(3 * s.b + r, 3 * s.b + c, h(r, c));
        t.emplace_back(3 * s.a + r, 3 * s.b + c, -h(r, c));
        t.emplace_back(3 * s.b + r, 3 * s.a + c, -h(r, c));
      }
    }
  }
  hess->resize(3 * n, 3 * n);
  hess->setFromTriplets(t.begin(), t.end());
}

/// Newton on the free coordinates (pins eliminated), from `x`, to |∇V| < 1e-11 N.
Eigen::VectorXd SolveStatics(const ClothModel& model, Eigen::VectorXd x, const Eigen::Vector3d& g) {
  const int n3 = 3 * model.num_particles();
  std::vector<int> free;
  for (int i = 0; i < model.num_particles(); ++i) {
    if (!model.is_pinned()[i]) {
      for (int c = 0; c < 3; ++c) free.push_back(3 * i + c);
    }
  }
  Eigen::SparseMatrix<double> select(free.size(), n3);
  for (std::size_t k = 0; k < free.size(); ++k) select.insert(k, free[k]) = 1.0;
  for (int iteration = 0; iteration < 50; ++iteration) {
    Eigen::VectorXd grad;
    Eigen::SparseMatrix<double> hess;
    EnergyGradientAndHessian(model, x, g, &grad, &hess);
    const Eigen::VectorXd r = select * grad;
    if (r.lpNorm<Eigen::Infinity>() < 1e-11) return x;
    Eigen::SparseMatrix<double> k = select * hess * select.transpose();
    Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> cholesky(k);
    EXPECT_EQ(cholesky.info(), Eigen::Success) << "Hessian not positive definite: not a minimum";
    x -= select.transpose() * cholesky.solve(r);
  }
  ADD_FAILURE() << "Newton did not converge";
  return x;
}

TEST(HangingCloth, SettlesToTheStaticEquilibriumOfNewtonsMethod) {
  for (SolverMethod method : {SolverMethod::kPcg, SolverMethod::kDirect}) {
    // Strong air drag settles the sway quickly; drag does not move the equilibrium.
    Material material;
    material.air_drag = 1.0;
    SceneDescription scene = test::HangScene(11, material);
    scene.solver.method = method;
    scene.solver.tolerance = 1e-8;
    auto sim = Simulation::Build(scene);
    for (int f = 0; f < 60 * 15; ++f) sim->AdvanceFrame();  // 15 s
    const auto& model = sim->model();
    const Eigen::VectorXd settled =
        Eigen::Map<const Eigen::VectorXd>(sim->state().positions.data(), 3 * model.num_particles());
    const Eigen::VectorXd statics = SolveStatics(model, settled, scene.gravity);
    // Tolerance: 0.1 mm on a 1 m sheet whose corners sag about 1 m.
    EXPECT_LT((settled - statics).lpNorm<Eigen::Infinity>(), 1e-4) << SolverMethodName(method);
    // And it really hangs: the free corners are far below the pins.
    EXPECT_LT(statics.minCoeff(), -0.5);
  }
}

}  // namespace
}  // namespace costume::sim
