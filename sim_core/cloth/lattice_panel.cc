#include "sim_core/cloth/lattice_panel.h"

#include <cmath>
#include <limits>

#include "sim_core/common/input_error.h"

namespace costume::sim {

namespace {

void ValidatePanel(const LatticePanel& panel, const std::string& name) {
  const std::string p = "garment '" + name + "' panel.";
  RequireInRange(p + "cols", panel.cols, 2, 1025, "");
  RequireInRange(p + "rows", panel.rows, 2, 1025, "");
  RequirePositive(p + "width", panel.width, "m");
  RequirePositive(p + "height", panel.height, "m");
  for (int c = 0; c < 3; ++c) RequireFinite(p + "origin", panel.origin[c], "m");
  RequireInRange(p + "u_axis length", panel.u_axis.norm(), 1 - 1e-6, 1 + 1e-6, "");
  RequireInRange(p + "v_axis length", panel.v_axis.norm(), 1 - 1e-6, 1 + 1e-6, "");
  RequireInRange(p + "u_axis·v_axis", panel.u_axis.dot(panel.v_axis), -1e-6, 1e-6, "");
}

/// Spring constant of a kind: the material's per-spring override when set, else `derived`.
double SpringConstant(double override_k, double derived) {
  return override_k > 0 ? override_k : derived;
}

struct LatticeBuilder {
  const LatticePanel& panel;
  const Material& material;
  ClothModelData& data;

  int Index(int i, int j) const { return i * panel.cols + j; }

  void AddSpring(int i0, int j0, int i1, int j1, SpringKind kind, double k) {
    if (i1 < 0 || i1 >= panel.rows || j1 < 0 || j1 >= panel.cols) return;
    Spring s;
    s.a = Index(i0, j0);
    s.b = Index(i1, j1);
    s.kind = kind;
    s.stiffness = k;
    s.damping = material.damping * k;
    s.rest_length = (data.rest_positions.row(s.b) - data.rest_positions.row(s.a)).norm();
    data.springs.push_back(s);
  }

  /// Adds each particle's springs towards larger indices only, so every pair appears once.
  void AddSprings(double du, double dv) {
    const double k_struct = SpringConstant(material.structural_spring_k,
                                           material.stretch_stiffness);
    const double k_shear = SpringConstant(material.shear_spring_k, material.shear_stiffness);
    const double k_bend_u = SpringConstant(material.bending_spring_k,
                                           material.bending_rigidity / (du * du));
    const double k_bend_v = SpringConstant(material.bending_spring_k,
                                           material.bending_rigidity / (dv * dv));
    for (int i = 0; i < panel.rows; ++i) {
      for (int j = 0; j < panel.cols; ++j) {
        AddSpring(i, j, i, j + 1, SpringKind::kStructural, k_struct);
        AddSpring(i, j, i + 1, j, SpringKind::kStructural, k_struct);
        AddSpring(i, j, i + 1, j + 1, SpringKind::kShear, k_shear);
        AddSpring(i, j, i + 1, j - 1, SpringKind::kShear, k_shear);
        AddSpring(i, j, i, j + 2, SpringKind::kBending, k_bend_u);
        AddSpring(i, j, i + 2, j, SpringKind::kBending, k_bend_v);
      }
    }
  }

  /// Two triangles per cell, the diagonal alternating so the mesh has no preferred direction.
  void AddTriangles() {
    for (int i = 0; i + 1 < panel.rows; ++i) {
      for (int j = 0; j + 1 < panel.cols; ++j) {
        const int a = Index(i, j), b = Index(i, j + 1), c = Index(i + 1, j + 1),
                  d = Index(i + 1, j);
        if ((i + j) % 2 == 0) {
          data.triangles.emplace_back(a, d, c);
          data.triangles.emplace_back(a, c, b);
        } else {
          data.triangles.emplace_back(a, d, b);
          data.triangles.emplace_back(b, d, c);
        }
      }
    }
  }
};

}  // namespace

ClothModelData BuildLatticePanel(const LatticePanel& panel, const Material& material,
                                 const std::string& name) {
  ValidatePanel(panel, name);
  ValidateMaterial(material, "garment '" + name + "' material");
  const int n = panel.rows * panel.cols;
  const double du = panel.width / (panel.cols - 1);
  const double dv = panel.height / (panel.rows - 1);
  ClothModelData data;
  data.name = name;
  data.lattice_rows = panel.rows;
  data.lattice_cols = panel.cols;
  data.rest_positions.resize(n, 3);
  for (int i = 0; i < panel.rows; ++i) {
    for (int j = 0; j < panel.cols; ++j) {
      data.rest_positions.row(i * panel.cols + j) =
          (panel.origin + j * du * panel.u_axis + i * dv * panel.v_axis).transpose();
    }
  }
  // Even mass: the benchmark scenes spread the sheet's mass evenly, so the total is exact.
  const double area = panel.width * panel.height;
  data.masses = Eigen::VectorXd::Constant(n, material.density * area / n);
  data.areas = Eigen::VectorXd::Constant(n, area / n);
  data.drag = material.air_drag * data.areas;
  LatticeBuilder builder{panel, material, data};
  builder.AddSprings(du, dv);
  builder.AddTriangles();
  return data;
}

std::vector<int> FindNearestParticles(const Points& positions,
                                      const std::vector<Eigen::Vector3d>& points,
                                      double tolerance, const std::string& context) {
  std::vector<int> result;
  for (const Eigen::Vector3d& point : points) {
    int best = -1;
    double best_distance = std::numeric_limits<double>::infinity();
    for (Eigen::Index i = 0; i < positions.rows(); ++i) {
      const double d = (positions.row(i).transpose() - point).norm();
      if (d < best_distance) {
        best_distance = d;
        best = static_cast<int>(i);
      }
    }
    if (best < 0 || best_distance > tolerance) {
      throw InputError(context + ": pin point (" + FormatValue(point.x()) + ", " +
                       FormatValue(point.y()) + ", " + FormatValue(point.z()) +
                       ") m has no particle within pin_tolerance = " + FormatValue(tolerance) +
                       " m (nearest is " + FormatValue(best_distance) + " m away)");
    }
    result.push_back(best);
  }
  return result;
}

}  // namespace costume::sim
