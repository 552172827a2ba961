#include "frontend/control_panels.h"

#include <QFormLayout>
#include <QGridLayout>
#include <QLabel>
#include <cmath>
#include <optional>

#include "sim_core/avatar/hanim.h"

namespace costume::frontend {
namespace {

QDoubleSpinBox* Field(const FieldRange& range, int decimals, const QString& unit,
                      const QString& tip) {
  auto* box = new QDoubleSpinBox;
  box->setDecimals(decimals);
  box->setRange(range.minimum, range.maximum);
  box->setSuffix(" " + unit);
  box->setToolTip(tip + QString(" [%1 … %2 %3]").arg(range.minimum).arg(range.maximum).arg(unit));
  box->setKeyboardTracking(false);
  return box;
}

/// True when `value` is finite and inside the box's range; else the reason in `*reason`.
bool Fits(const QDoubleSpinBox* box, double value, const QString& field, QString* reason) {
  if (std::isfinite(value) && value >= box->minimum() && value <= box->maximum()) return true;
  if (reason) {
    *reason = QString("%1 = %2: allowed range [%3, %4]%5")
                  .arg(field)
                  .arg(value)
                  .arg(box->minimum())
                  .arg(box->maximum())
                  .arg(box->suffix());
  }
  return false;
}

bool FitsInt(const QSpinBox* box, int value, const QString& field, QString* reason) {
  if (value >= box->minimum() && value <= box->maximum()) return true;
  if (reason) {
    *reason = QString("%1 = %2: allowed range [%3, %4]")
                  .arg(field)
                  .arg(value)
                  .arg(box->minimum())
                  .arg(box->maximum());
  }
  return false;
}

}  // namespace

// ---- MaterialPanel --------------------------------------------------------------------------

MaterialPanel::MaterialPanel(std::vector<FabricPreset> presets, QWidget* parent)
    : QGroupBox("Fabric", parent), presets_(std::move(presets)) {
  const FabricRanges r = ranges();
  density = Field(r.density, 3, "kg/m²", "Mass per area");
  stretch = Field(r.stretch, 1, "N/m", "Sheet stretch stiffness");
  shear = Field(r.shear, 1, "N/m", "Sheet shear stiffness");
  bending = Field(r.bending, 8, "N·m", "Bending rigidity");
  damping = Field(r.damping, 5, "s", "Spring damping time (c = damping · k)");
  friction = Field(r.friction, 2, "",
                   "The fabric's Coulomb coefficient: a contact's is the geometric mean of "
                   "this and the body's (the skin's, a sphere's)");
  air_drag = Field(r.air_drag, 3, "N·s/m³", "Air drag per m² of cloth");
  preset = new QComboBox;
  preset->addItem("custom");
  for (const FabricPreset& p : presets_) preset->addItem(QString::fromStdString(p.name));
  apply = new QPushButton("Apply fabric");
  auto* form = new QFormLayout(this);
  form->addRow("Preset", preset);
  form->addRow("Mass per area", density);
  form->addRow("Stretch stiffness", stretch);
  form->addRow("Shear stiffness", shear);
  form->addRow("Bending rigidity", bending);
  form->addRow("Damping", damping);
  form->addRow("Friction", friction);
  form->addRow("Air drag", air_drag);
  form->addRow(apply);
  SetMaterial(sim::Material{});
  connect(preset, &QComboBox::currentIndexChanged, this, [this](int index) {
    if (index >= 1) {
      SetMaterial(presets_[static_cast<std::size_t>(index - 1)].material);
      name_ = QString::fromStdString(presets_[static_cast<std::size_t>(index - 1)].name);
    }
  });
  connect(apply, &QPushButton::clicked, this, [this] { emit materialRequested(material()); });
}

sim::Material MaterialPanel::material() const {
  sim::Material m;
  m.name = name_.toStdString();
  m.density = density->value();
  m.stretch_stiffness = stretch->value();
  m.shear_stiffness = shear->value();
  m.bending_rigidity = bending->value();
  m.damping = damping->value();
  m.friction = friction->value();
  m.air_drag = air_drag->value();
  return m;
}

bool MaterialPanel::SetMaterial(const sim::Material& m, QString* reason) {
  if (!Fits(density, m.density, "density", reason) ||
      !Fits(stretch, m.stretch_stiffness, "stretch_stiffness", reason) ||
      !Fits(shear, m.shear_stiffness, "shear_stiffness", reason) ||
      !Fits(bending, m.bending_rigidity, "bending_rigidity", reason) ||
      !Fits(damping, m.damping, "damping", reason) ||
      !Fits(friction, m.friction, "friction", reason) ||
      !Fits(air_drag, m.air_drag, "air_drag", reason)) {
    return false;
  }
  density->setValue(m.density);
  stretch->setValue(m.stretch_stiffness);
  shear->setValue(m.shear_stiffness);
  bending->setValue(m.bending_rigidity);
  damping->setValue(m.damping);
  friction->setValue(m.friction);
  air_drag->setValue(m.air_drag);
  name_ = QString::fromStdString(m.name);
  return true;
}

// ---- SolverPanel ----------------------------------------------------------------------------

SolverPanel::SolverPanel(QWidget* parent) : QGroupBox("Solver", parent) {
  method = new QComboBox;
  method->addItems({"Flat PCG", "Hierarchical (pyramid)", "Multigrid PCG", "Direct (Cholesky)"});
  coarse_operator = new QComboBox;
  coarse_operator->addItems({"Rediscretised models", "Galerkin (PᵀAP)"});
  coarse_operator->setToolTip(
      "Multigrid's coarse-level matrices: each level's own cloth model at the restricted "
      "state, or products of level 0's matrix (fewer iterations at tight tolerances)");
  levels = new QSpinBox;
  levels->setRange(0, 12);
  levels->setSpecialValueText("all");
  levels->setToolTip("Pyramid levels counting level 0; 'all' = as many as the cloth allows");
  tolerance = Field({1e-6, 0.5}, 6, "", "PCG relative residual tolerance");
  max_iterations = new QSpinBox;
  max_iterations->setRange(1, 100000);
  substeps = new QSpinBox;
  substeps->setRange(1, 64);
  substeps->setToolTip("Implicit steps per 1/60 s frame");
  strain_limit = Field({0.0, 10.0}, 3, "", "Largest strain after a step; 0 = off");
  apply = new QPushButton("Apply solver");
  auto* form = new QFormLayout(this);
  form->addRow("Method", method);
  form->addRow("Coarse levels", coarse_operator);
  form->addRow("Levels", levels);
  form->addRow("Tolerance", tolerance);
  form->addRow("Iteration cap", max_iterations);
  form->addRow("Substeps", substeps);
  form->addRow("Strain limit", strain_limit);
  form->addRow(apply);
  SetSettings(sim::SolverSettings{});
  connect(method, &QComboBox::currentIndexChanged, this, [this] { UpdateEnabled(); });
  connect(apply, &QPushButton::clicked, this, [this] { emit solverRequested(settings()); });
}

void SolverPanel::UpdateEnabled() {
  const auto m = static_cast<sim::SolverMethod>(method->currentIndex());
  levels->setEnabled(m == sim::SolverMethod::kHierarchical || m == sim::SolverMethod::kMultigrid);
  coarse_operator->setEnabled(m == sim::SolverMethod::kMultigrid);
  tolerance->setEnabled(m != sim::SolverMethod::kDirect);
  max_iterations->setEnabled(m != sim::SolverMethod::kDirect);
}

sim::SolverSettings SolverPanel::settings() const {
  sim::SolverSettings s;
  s.method = static_cast<sim::SolverMethod>(method->currentIndex());
  s.coarse_operator = coarse_operator->currentIndex() == 1 ? sim::CoarseOperator::kGalerkin
                                                           : sim::CoarseOperator::kRediscretised;
  s.levels = levels->value();
  s.tolerance = tolerance->value();
  s.max_iterations = max_iterations->value();
  s.substeps = substeps->value();
  s.strain_limit = strain_limit->value();
  return s;
}

bool SolverPanel::SetSettings(const sim::SolverSettings& s, QString* reason) {
  if (!FitsInt(levels, s.levels, "levels", reason) ||
      !Fits(tolerance, s.tolerance, "tolerance", reason) ||
      !FitsInt(max_iterations, s.max_iterations, "max_iterations", reason) ||
      !FitsInt(substeps, s.substeps, "substeps", reason) ||
      !Fits(strain_limit, s.strain_limit, "strain_limit", reason)) {
    return false;
  }
  method->setCurrentIndex(static_cast<int>(s.method));
  coarse_operator->setCurrentIndex(s.coarse_operator == sim::CoarseOperator::kGalerkin ? 1 : 0);
  levels->setValue(s.levels);
  tolerance->setValue(s.tolerance);
  max_iterations->setValue(s.max_iterations);
  substeps->setValue(s.substeps);
  strain_limit->setValue(s.strain_limit);
  UpdateEnabled();
  return true;
}

// ---- CollisionPanel -------------------------------------------------------------------------

CollisionPanel::CollisionPanel(QWidget* parent) : QGroupBox("Collision", parent) {
  method = new QComboBox;
  method->addItems({"Mesh (accurate)", "Superquadrics (fast)"});
  method->setToolTip(
      "Mesh: the skinned mesh through a bounding-volume tree, for any motion. Superquadrics: "
      "one per body segment with the skin mapped over it, fastest on a looping clip's later "
      "passes, when its map drawings are reused (docs/collision.md)");
  thickness_mm = Field({0.0, 50.0}, 1, "mm", "Cloth kept off the skin (and off itself)");
  friction = Field({0.0, 2.0}, 2, "",
                   "The skin's Coulomb coefficient: a contact's is the geometric mean of "
                   "this and the fabric's friction");
  max_skin_travel_cm = Field({0.0, 100.0}, 1, "cm",
                             "Farthest the skin near the cloth may move in one step: a frame "
                             "in which a limb moves farther is split into more steps, so a "
                             "kick does not pass through the cloth; 0 = never split");
  max_skin_travel_cm->setSpecialValueText("never split");
  max_steps_per_frame = new QSpinBox;
  max_steps_per_frame->setRange(1, sim::kMaxStepsPerFrame);
  max_steps_per_frame->setToolTip("Most steps a frame is split into for the skin's travel");
  map_memory_mb = Field({0.0, sim::kMaxSuperquadricMapMb}, 0, "MB",
                        "Superquadrics: memory for map drawings reused when the skin comes "
                        "back (a looping clip); 0 = draw every map afresh");
  self_collision = new QCheckBox("Cloth against itself");
  self_collision->setToolTip(
      "Self-collision: keeps the cloth from passing through itself. Off costs nothing; on, "
      "it slows a frame, most on fine garments (90 around: no longer real time; "
      "docs/collision.md, \"The body once more\")");
  apply = new QPushButton("Apply collision");
  auto* form = new QFormLayout(this);
  form->addRow("Method", method);
  form->addRow("Thickness", thickness_mm);
  form->addRow("Skin friction", friction);
  form->addRow("Skin travel per step", max_skin_travel_cm);
  form->addRow("Steps per frame, at most", max_steps_per_frame);
  form->addRow("Map memory", map_memory_mb);
  form->addRow(self_collision);
  form->addRow(apply);
  SetSettings(sim::CollisionSettingsOf(sim::SceneDescription{}));
  connect(method, &QComboBox::currentIndexChanged, this, [this] { UpdateEnabled(); });
  connect(max_skin_travel_cm, &QDoubleSpinBox::valueChanged, this, [this] { UpdateEnabled(); });
  connect(apply, &QPushButton::clicked, this, [this] { emit collisionRequested(settings()); });
}

void CollisionPanel::UpdateEnabled() {
  map_memory_mb->setEnabled(method->currentIndex() == 1);
  max_steps_per_frame->setEnabled(max_skin_travel_cm->value() > 0.0);
}

sim::CollisionSettings CollisionPanel::settings() const {
  sim::CollisionSettings s;
  s.method = method->currentIndex() == 1 ? sim::BodyCollisionMethod::kSuperquadric
                                         : sim::BodyCollisionMethod::kMesh;
  s.thickness = thickness_mm->value() / 1000.0;
  s.friction = friction->value();
  s.max_skin_travel = max_skin_travel_cm->value() / 100.0;
  s.max_steps_per_frame = max_steps_per_frame->value();
  s.superquadric_map_mb = map_memory_mb->value();
  s.self_collision = self_collision->isChecked();
  return s;
}

bool CollisionPanel::SetSettings(const sim::CollisionSettings& s, QString* reason) {
  if (!Fits(thickness_mm, s.thickness * 1000.0, "thickness", reason) ||
      !Fits(friction, s.friction, "friction", reason) ||
      !Fits(max_skin_travel_cm, s.max_skin_travel * 100.0, "max_skin_travel", reason) ||
      !FitsInt(max_steps_per_frame, s.max_steps_per_frame, "max_steps_per_frame", reason) ||
      !Fits(map_memory_mb, s.superquadric_map_mb, "superquadric_map_mb", reason)) {
    return false;
  }
  method->setCurrentIndex(s.method == sim::BodyCollisionMethod::kSuperquadric ? 1 : 0);
  thickness_mm->setValue(s.thickness * 1000.0);
  friction->setValue(s.friction);
  max_skin_travel_cm->setValue(s.max_skin_travel * 100.0);
  max_steps_per_frame->setValue(s.max_steps_per_frame);
  map_memory_mb->setValue(s.superquadric_map_mb);
  self_collision->setChecked(s.self_collision);
  UpdateEnabled();
  return true;
}

// ---- PosturePanel ---------------------------------------------------------------------------

const std::vector<std::string>& PostureJoints() {
  static const std::vector<std::string> joints = {
      "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_hip",
      "r_hip",      "l_knee",     "r_knee",  "vl5",     "skullbase"};
  return joints;
}

PosturePanel::PosturePanel(QWidget* parent) : QGroupBox("Avatar posture", parent) {
  auto* grid = new QGridLayout(this);
  grid->addWidget(new QLabel("joint"), 0, 0);
  grid->addWidget(new QLabel("about x"), 0, 1);
  grid->addWidget(new QLabel("about y"), 0, 2);
  grid->addWidget(new QLabel("about z"), 0, 3);
  int row = 1;
  for (const std::string& joint : PostureJoints()) {
    grid->addWidget(new QLabel(QString::fromStdString(joint)), row, 0);
    std::array<QDoubleSpinBox*, 3> boxes{};
    for (int axis = 0; axis < 3; ++axis) {
      boxes[axis] = Field({-180.0, 180.0}, 1, "°", "Rotation about the joint's rest axis");
      grid->addWidget(boxes[axis], row, axis + 1);
    }
    angles_.push_back(boxes);
    ++row;
  }
  heading_ = Field({-180.0, 180.0}, 1, "°", "The avatar's turn about the vertical axis");
  grid->addWidget(new QLabel("heading"), row, 0);
  grid->addWidget(heading_, row, 1);
  ++row;
  // The clip's arms turned out from the body, so that forearms swinging through the hips
  // (a clip captured on a narrower body) do not tear the cloth caught there.
  auto_spread = new QCheckBox("auto");
  auto_spread->setChecked(true);
  auto_spread->setToolTip("The simulation turns each arm out as far as keeps the clip's "
                          "forearms and hands 1 cm off the body (up to 15°)");
  grid->addWidget(new QLabel("arm spread"), row, 0);
  grid->addWidget(auto_spread, row, 1);
  const QString sides[2] = {"left", "right"};
  for (int side = 0; side < 2; ++side) {
    spread[side] = Field({0.0, sim::kMaxArmSpreadDegrees}, 1, "°",
                         "The " + sides[side] + " arm turned out from the body");
    spread[side]->setPrefix(sides[side] + " ");
    spread[side]->setEnabled(false);
    grid->addWidget(spread[side], row, side + 2);
  }
  connect(auto_spread, &QCheckBox::toggled, this, [this](bool automatic) {
    for (QDoubleSpinBox* box : spread) box->setEnabled(!automatic);
    spread_edited_ = true;
  });
  for (QDoubleSpinBox* box : spread) {
    connect(box, &QDoubleSpinBox::valueChanged, this, [this] { spread_edited_ = true; });
  }
  apply = new QPushButton("Apply posture");
  grid->addWidget(apply, row + 1, 0, 1, 4);
  connect(apply, &QPushButton::clicked, this, [this] {
    const sim::ArmSpreadRequest request = arm_spread();
    spread_edited_ = false;
    emit postureRequested(joints(), heading(), request);
  });
}

void PosturePanel::SetPosture(const sim::Pose& posture, const sim::Skeleton& skeleton) {
  for (std::size_t i = 0; i < angles_.size(); ++i) {
    const std::optional<sim::HAnimJoint> joint = sim::ParseHAnimName(PostureJoints()[i]);
    const int index = joint ? skeleton.Find(*joint) : -1;
    const Eigen::Vector3d degrees =
        index >= 0 && index < static_cast<int>(posture.rotations.size())
            ? sim::PostureDegrees(posture.rotations[index])
            : Eigen::Vector3d::Zero();
    for (int axis = 0; axis < 3; ++axis) angles_[i][axis]->setValue(degrees[axis]);
  }
  // The placement's turn about +y (PostureRotation({0, heading, 0})): where it takes +z.
  const Eigen::Vector3d forward = posture.orientation.normalized() * Eigen::Vector3d::UnitZ();
  heading_->setValue(std::atan2(forward.x(), forward.z()) * 180.0 / M_PI);
}

sim::ArmSpreadRequest PosturePanel::arm_spread() const {
  sim::ArmSpreadRequest request;
  if (!spread_edited_) return request;
  request.kind = auto_spread->isChecked() ? sim::ArmSpreadRequest::Kind::kAuto
                                          : sim::ArmSpreadRequest::Kind::kGiven;
  for (int side = 0; side < 2; ++side) request.angle[side] = spread[side]->value() * M_PI / 180.0;
  return request;
}

void PosturePanel::SetArmSpread(bool automatic, const std::array<double, 2>& angle) {
  auto_spread->setChecked(automatic);
  for (int side = 0; side < 2; ++side) spread[side]->setValue(angle[side] * 180.0 / M_PI);
  spread_edited_ = false;
}

std::vector<JointAngles> PosturePanel::joints() const {
  std::vector<JointAngles> out;
  for (std::size_t i = 0; i < angles_.size(); ++i) {
    out.push_back({PostureJoints()[i], Eigen::Vector3d(angles_[i][0]->value(),
                                                       angles_[i][1]->value(),
                                                       angles_[i][2]->value())});
  }
  return out;
}

QDoubleSpinBox* PosturePanel::angle(const std::string& joint, int axis) const {
  for (std::size_t i = 0; i < angles_.size(); ++i) {
    if (PostureJoints()[i] == joint) return angles_[i][static_cast<std::size_t>(axis)];
  }
  return nullptr;
}

}  // namespace costume::frontend
