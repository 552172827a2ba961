// The settings' conversions used by both the GUI (sending) and the simulation server
// (applying): every method and coarse operator survives the trip, unknown codes are refused
// naming the field and its allowed values.
#include "bus/settings_codec.h"

#include <gtest/gtest.h>

#include "sim_core/common/input_error.h"

namespace costume::bus {
namespace {

using P = costume_lcm::solver_parameters;

TEST(SettingsCodec, EverySolverSettingSurvivesTheTrip) {
  for (sim::SolverMethod method : {sim::SolverMethod::kPcg, sim::SolverMethod::kHierarchical,
                                   sim::SolverMethod::kMultigrid, sim::SolverMethod::kDirect}) {
    for (sim::CoarseOperator op : {sim::CoarseOperator::kGalerkin, sim::CoarseOperator::kRediscretised}) {
      sim::SolverSettings s;
      s.method = method;
      s.coarse_operator = op;
      s.levels = 4;
      s.tolerance = 3e-3;
      s.max_iterations = 77;
      s.substeps = 3;
      s.strain_limit = 0.25;
      const sim::SolverSettings back = FromMessage(ToMessage(s));
      EXPECT_EQ(back.method, s.method);
      EXPECT_EQ(back.coarse_operator, s.coarse_operator);
      EXPECT_EQ(back.levels, 4);
      EXPECT_DOUBLE_EQ(back.tolerance, 3e-3);
      EXPECT_EQ(back.max_iterations, 77);
      EXPECT_EQ(back.substeps, 3);
      EXPECT_DOUBLE_EQ(back.strain_limit, 0.25);
    }
  }
}

TEST(SettingsCodec, CodesAreTheMessagesConstants) {
  sim::SolverSettings s;
  s.method = sim::SolverMethod::kMultigrid;
  s.coarse_operator = sim::CoarseOperator::kGalerkin;
  EXPECT_EQ(ToMessage(s).method, P::METHOD_MULTIGRID);
  EXPECT_EQ(ToMessage(s).coarse_operator, P::COARSE_GALERKIN);
  // A zeroed message (an old sender's) is flat PCG with rediscretised coarse levels.
  const sim::SolverSettings zero = FromMessage(P{});
  EXPECT_EQ(zero.method, sim::SolverMethod::kPcg);
  EXPECT_EQ(zero.coarse_operator, sim::CoarseOperator::kRediscretised);
}

TEST(SettingsCodec, UnknownCodesAreRefusedNamingTheField) {
  P bad{};
  bad.method = 9;
  try {
    FromMessage(bad);
    FAIL() << "method 9 accepted";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("solver.method = 9"), std::string::npos) << e.what();
  }
  bad.method = P::METHOD_MULTIGRID;
  bad.coarse_operator = -1;
  try {
    FromMessage(bad);
    FAIL() << "coarse operator -1 accepted";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("solver.coarse_operator = -1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("galerkin"), std::string::npos) << e.what();
  }
}

TEST(SettingsCodec, MaterialFieldsSurviveTheTrip) {
  sim::Material m;
  m.name = "velvet";
  m.density = 0.31;
  m.stretch_stiffness = 812.0;
  m.shear_stiffness = 51.0;
  m.bending_rigidity = 2e-5;
  m.damping = 0.07;
  m.air_drag = 0.4;
  m.friction = 0.6;
  m.structural_spring_k = 1.5;
  m.shear_spring_k = 2.5;
  m.bending_spring_k = 3.5;
  const sim::Material back = FromMessage(ToMessage(m));
  EXPECT_EQ(back.name, "velvet");
  EXPECT_DOUBLE_EQ(back.density, 0.31);
  EXPECT_DOUBLE_EQ(back.stretch_stiffness, 812.0);
  EXPECT_DOUBLE_EQ(back.shear_stiffness, 51.0);
  EXPECT_DOUBLE_EQ(back.bending_rigidity, 2e-5);
  EXPECT_DOUBLE_EQ(back.damping, 0.07);
  EXPECT_DOUBLE_EQ(back.air_drag, 0.4);
  EXPECT_DOUBLE_EQ(back.friction, 0.6);
  EXPECT_DOUBLE_EQ(back.structural_spring_k, 1.5);
  EXPECT_DOUBLE_EQ(back.shear_spring_k, 2.5);
  EXPECT_DOUBLE_EQ(back.bending_spring_k, 3.5);
}

TEST(SettingsCodec, EveryCollisionSettingSurvivesTheTrip) {
  for (sim::BodyCollisionMethod method :
       {sim::BodyCollisionMethod::kSuperquadric, sim::BodyCollisionMethod::kMesh}) {
    for (bool self : {false, true}) {
      sim::CollisionSettings s;
      s.method = method;
      s.thickness = 0.007;
      s.friction = 0.8;
      s.max_skin_travel = 0.03;
      s.max_steps_per_frame = 12;
      s.superquadric_map_mb = 64.0;
      s.self_collision = self;
      const sim::CollisionSettings back = FromMessage(ToMessage(s));
      EXPECT_EQ(back.method, method);
      EXPECT_DOUBLE_EQ(back.thickness, 0.007);
      EXPECT_DOUBLE_EQ(back.friction, 0.8);
      EXPECT_DOUBLE_EQ(back.max_skin_travel, 0.03);
      EXPECT_EQ(back.max_steps_per_frame, 12);
      EXPECT_DOUBLE_EQ(back.superquadric_map_mb, 64.0);
      EXPECT_EQ(back.self_collision, self);
    }
  }
  sim::CollisionSettings mesh;
  mesh.method = sim::BodyCollisionMethod::kMesh;
  EXPECT_EQ(ToMessage(mesh).method, costume_lcm::collision_parameters::METHOD_MESH);
}

TEST(SettingsCodec, AnUnknownCollisionMethodIsRefusedNamingTheField) {
  costume_lcm::collision_parameters bad{};
  bad.method = 2;
  try {
    FromMessage(bad);
    FAIL() << "method 2 accepted";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("collision.method = 2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("superquadric"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace costume::bus
