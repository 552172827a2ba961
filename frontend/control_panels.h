#pragma once
/// @file
/// The parameter panels of the main window: fabric, solver, collision and the avatar's
/// posture. Each holds validated fields with units and emits one request signal when the
/// designer applies it; the window turns requests into commands (command_sender.h). Ranges
/// are physical ranges (docs/frontend.md): a spin box refuses a typed value outside its
/// range, and the Set* methods refuse (returning false with the reason) values outside it
/// too.

#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QGroupBox>
#include <QPushButton>
#include <QSpinBox>
#include <QString>
#include <vector>

#include "frontend/catalog_source.h"
#include "frontend/command_sender.h"
#include "sim_core/cloth/material.h"
#include "sim_core/scene/scene_description.h"

namespace costume::frontend {

/// Range of one physical field [its unit].
struct FieldRange {
  double minimum = 0.0;
  double maximum = 1.0;
};

/// The fabric's ranges: mass per area, stretch, shear, bending, damping, friction, air drag.
struct FabricRanges {
  FieldRange density{0.01, 2.0};              ///< [kg/m²]: organza 0.02 … heavy leather 1.5
  FieldRange stretch{1.0, 1e6};               ///< [N/m]
  FieldRange shear{1.0, 1e6};                 ///< [N/m]
  FieldRange bending{0.0, 1e-2};              ///< [N·m]
  FieldRange damping{0.0, 0.1};               ///< [s]
  FieldRange friction{0.0, 2.0};              ///< [-]
  FieldRange air_drag{0.0, 1.0};              ///< [N·s/m per m²]
};

/// Fabric fields, a preset combo and Apply (KIND_SET_MATERIAL for every garment).
class MaterialPanel : public QGroupBox {
  Q_OBJECT

 public:
  MaterialPanel(std::vector<FabricPreset> presets, QWidget* parent = nullptr);
  /// The fabric the fields show.
  sim::Material material() const;
  /// Shows `material`; false (fields unchanged) with the reason when a value is outside its
  /// range or not finite.
  bool SetMaterial(const sim::Material& material, QString* reason = nullptr);
  static FabricRanges ranges() { return {}; }

  QDoubleSpinBox* density = nullptr;
  QDoubleSpinBox* stretch = nullptr;
  QDoubleSpinBox* shear = nullptr;
  QDoubleSpinBox* bending = nullptr;
  QDoubleSpinBox* damping = nullptr;
  QDoubleSpinBox* friction = nullptr;
  QDoubleSpinBox* air_drag = nullptr;
  QComboBox* preset = nullptr;
  QPushButton* apply = nullptr;

 signals:
  void materialRequested(const sim::Material& material);

 private:
  std::vector<FabricPreset> presets_;
  QString name_ = "custom";
};

/// Solver method, pyramid levels, tolerance, iteration cap, substeps; Apply (KIND_SET_SOLVER).
class SolverPanel : public QGroupBox {
  Q_OBJECT

 public:
  explicit SolverPanel(QWidget* parent = nullptr);
  sim::SolverSettings settings() const;
  /// Shows `settings`; false with the reason for a value outside the fields' ranges.
  bool SetSettings(const sim::SolverSettings& settings, QString* reason = nullptr);

  QComboBox* method = nullptr;
  /// Multigrid only: index 0 rediscretised coarse models, 1 Galerkin products (PᵀAP).
  QComboBox* coarse_operator = nullptr;
  QSpinBox* levels = nullptr;
  QDoubleSpinBox* tolerance = nullptr;
  QSpinBox* max_iterations = nullptr;
  QSpinBox* substeps = nullptr;
  QDoubleSpinBox* strain_limit = nullptr;
  QPushButton* apply = nullptr;

 signals:
  void solverRequested(const sim::SolverSettings& settings);

 private:
  void UpdateEnabled();
};

/// Collision method, thickness, friction against the skin, the skin's travel per step and
/// its step cap, the superquadric method's map memory, self-collision; Apply
/// (KIND_SET_COLLISION). Lengths are shown in mm and cm, sent in metres.
class CollisionPanel : public QGroupBox {
  Q_OBJECT

 public:
  explicit CollisionPanel(QWidget* parent = nullptr);
  sim::CollisionSettings settings() const;
  /// Shows `settings`; false with the reason for a value outside the fields' ranges.
  bool SetSettings(const sim::CollisionSettings& settings, QString* reason = nullptr);

  /// Index 0 the mesh method (accurate), 1 superquadrics (fast).
  QComboBox* method = nullptr;
  QDoubleSpinBox* thickness_mm = nullptr;
  QDoubleSpinBox* friction = nullptr;
  QDoubleSpinBox* max_skin_travel_cm = nullptr;
  QSpinBox* max_steps_per_frame = nullptr;
  QDoubleSpinBox* map_memory_mb = nullptr;
  QCheckBox* self_collision = nullptr;
  QPushButton* apply = nullptr;

 signals:
  void collisionRequested(const sim::CollisionSettings& settings);

 private:
  void UpdateEnabled();
};

/// The H-Anim joints the posture panel offers.
const std::vector<std::string>& PostureJoints();

/// Angles of a few major joints and the heading; Apply (KIND_SET_POSTURE).
class PosturePanel : public QGroupBox {
  Q_OBJECT

 public:
  explicit PosturePanel(QWidget* parent = nullptr);
  /// Every offered joint with its angles (zero rows included: they reset the joint).
  std::vector<JointAngles> joints() const;
  double heading() const { return heading_->value(); }
  /// The spin box of `joint`'s rotation about rest axis `axis` (0 x, 1 y, 2 z).
  QDoubleSpinBox* angle(const std::string& joint, int axis) const;
  QDoubleSpinBox* heading_box() const { return heading_; }
  /// The arms' spread asked for: kKeep until the designer changes the row (an automatic
  /// spread is not searched for again at each Apply: 0.01–0.5 s), then kAuto while
  /// `auto_spread` is checked, else the two angles, left and right [rad]
  /// (sim_core/scene/arm_spread.h).
  sim::ArmSpreadRequest arm_spread() const;
  /// Shows a scene's posture: each offered joint's angles (PostureDegrees; a joint the
  /// skeleton lacks at 0) and the heading about +y, so that Apply keeps what it does not
  /// change. Joints the panel does not offer are not shown (Apply returns them to rest).
  void SetPosture(const sim::Pose& posture, const sim::Skeleton& skeleton);
  /// Shows a scene's arms' spread: chosen by the simulation, or the angles it gives [rad].
  void SetArmSpread(bool automatic, const std::array<double, 2>& angle);
  QPushButton* apply = nullptr;
  QCheckBox* auto_spread = nullptr;
  std::array<QDoubleSpinBox*, 2> spread{};

 signals:
  void postureRequested(const std::vector<costume::frontend::JointAngles>& joints,
                        double heading_degrees, const costume::sim::ArmSpreadRequest& arm_spread);

 private:
  std::vector<std::array<QDoubleSpinBox*, 3>> angles_;
  QDoubleSpinBox* heading_ = nullptr;
  /// The spread row changed since it was last shown or applied.
  bool spread_edited_ = false;
};

}  // namespace costume::frontend
