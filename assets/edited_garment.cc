#include "assets/edited_garment.h"

#include <nlohmann/json.hpp>

#include <bit>
#include <cstring>

#include "sim_core/common/input_error.h"

namespace costume::assets {

namespace {

static_assert(std::endian::native == std::endian::little,
              "the edited-garment format is written little-endian by copying memory");

constexpr char kMagic[8] = {'C', 'D', 'G', 'A', 'R', 'M', 'N', 'T'};

class Writer {
 public:
  template <typename T>
  void Put(T value) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(&value);
    bytes_.insert(bytes_.end(), p, p + sizeof(T));
  }
  void PutBytes(const void* data, std::size_t size) {
    const auto* p = static_cast<const std::uint8_t*>(data);
    bytes_.insert(bytes_.end(), p, p + size);
  }
  std::vector<std::uint8_t> Take() { return std::move(bytes_); }

 private:
  std::vector<std::uint8_t> bytes_;
};

class Reader {
 public:
  Reader(const std::vector<std::uint8_t>& bytes, std::string source)
      : bytes_(bytes), source_(std::move(source)) {}
  template <typename T>
  T Get(const char* what) {
    T value;
    GetBytes(&value, sizeof(T), what);
    return value;
  }
  void GetBytes(void* out, std::size_t size, const char* what) {
    if (size > bytes_.size() - at_) {
      Fail(std::string("truncated in ") + what + " (at byte " + std::to_string(at_) + " of " +
           std::to_string(bytes_.size()) + ", needs " + std::to_string(size) + " more)");
    }
    std::memcpy(out, bytes_.data() + at_, size);
    at_ += size;
  }
  std::size_t remaining() const { return bytes_.size() - at_; }
  [[noreturn]] void Fail(const std::string& message) const {
    throw sim::InputError(source_ + ": edited garment: " + message);
  }

 private:
  const std::vector<std::uint8_t>& bytes_;
  std::size_t at_ = 0;
  std::string source_;
};

nlohmann::json MaterialJson(const sim::Material& m) {
  return {{"name", m.name},
          {"density", m.density},
          {"stretch_stiffness", m.stretch_stiffness},
          {"shear_stiffness", m.shear_stiffness},
          {"bending_rigidity", m.bending_rigidity},
          {"damping", m.damping},
          {"air_drag", m.air_drag},
          {"friction", m.friction},
          {"structural_spring_k", m.structural_spring_k},
          {"shear_spring_k", m.shear_spring_k},
          {"bending_spring_k", m.bending_spring_k}};
}

sim::Material MaterialFromJson(const nlohmann::json& j) {
  sim::Material m;
  m.name = j.at("name").get<std::string>();
  m.density = j.at("density").get<double>();
  m.stretch_stiffness = j.at("stretch_stiffness").get<double>();
  m.shear_stiffness = j.at("shear_stiffness").get<double>();
  m.bending_rigidity = j.at("bending_rigidity").get<double>();
  m.damping = j.at("damping").get<double>();
  m.air_drag = j.at("air_drag").get<double>();
  m.friction = j.at("friction").get<double>();
  m.structural_spring_k = j.at("structural_spring_k").get<double>();
  m.shear_spring_k = j.at("shear_spring_k").get<double>();
  m.bending_spring_k = j.at("bending_spring_k").get<double>();
  return m;
}

/// A count from the header: an integer in [lo, hi].
int Count(const nlohmann::json& header, const char* field, int lo, int hi, const Reader& reader) {
  const nlohmann::json& value = header.at(field);
  if (!value.is_number_integer() || value.get<long long>() < lo || value.get<long long>() > hi) {
    reader.Fail(std::string("header.") + field + " = " + value.dump() + ": allowed range [" +
                std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return value.get<int>();
}

void ReadDoubles(Reader& reader, Eigen::Ref<Eigen::VectorXd> out, const char* what) {
  reader.GetBytes(out.data(), sizeof(double) * out.size(), what);
}

}  // namespace

std::vector<std::uint8_t> WriteEditedGarment(const EditedGarment& garment) {
  const sim::ClothModel& model = *garment.model;
  const int n = model.num_particles();
  const bool has_drag = model.drag().size() == n && n > 0;
  nlohmann::json header = {
      {"name", model.name()},
      {"attached_to", garment.attached_to
                          ? nlohmann::json(std::string(sim::HAnimName(*garment.attached_to)))
                          : nlohmann::json(nullptr)},
      {"material", MaterialJson(garment.material)},
      {"num_particles", n},
      {"num_springs", model.num_springs()},
      {"num_pins", static_cast<int>(model.pinned().size())},
      {"num_triangles", static_cast<int>(model.triangles().size())},
      {"lattice_rows", model.lattice_rows()},
      {"lattice_cols", model.lattice_cols()},
      {"has_drag", has_drag}};
  const std::string text = header.dump();
  Writer w;
  w.PutBytes(kMagic, sizeof kMagic);
  w.Put<std::uint32_t>(kEditedGarmentVersion);
  w.Put<std::uint32_t>(static_cast<std::uint32_t>(text.size()));
  w.PutBytes(text.data(), text.size());
  w.PutBytes(model.rest_positions().data(), sizeof(double) * 3 * n);  // row-major: x y z
  w.PutBytes(model.masses().data(), sizeof(double) * n);
  w.PutBytes(model.areas().data(), sizeof(double) * n);
  if (has_drag) w.PutBytes(model.drag().data(), sizeof(double) * n);
  for (const sim::Spring& s : model.springs()) {
    w.Put<std::int32_t>(s.a);
    w.Put<std::int32_t>(s.b);
    w.Put<std::uint8_t>(static_cast<std::uint8_t>(s.kind));
    w.Put<double>(s.stiffness);
    w.Put<double>(s.damping);
    w.Put<double>(s.rest_length);
  }
  for (int p : model.pinned()) w.Put<std::int32_t>(p);
  for (const Eigen::Vector3i& t : model.triangles()) {
    for (int k = 0; k < 3; ++k) w.Put<std::int32_t>(t[k]);
  }
  return w.Take();
}

EditedGarment ReadEditedGarment(const std::vector<std::uint8_t>& bytes, const std::string& source) {
  Reader reader(bytes, source);
  char magic[8];
  reader.GetBytes(magic, sizeof magic, "the magic");
  if (std::memcmp(magic, kMagic, sizeof kMagic) != 0) {
    reader.Fail("not an edited garment (the file does not start with \"CDGARMNT\")");
  }
  const auto version = reader.Get<std::uint32_t>("the version");
  if (version != kEditedGarmentVersion) {
    reader.Fail("format version " + std::to_string(version) + ": this program reads version " +
                std::to_string(kEditedGarmentVersion));
  }
  const auto header_size = reader.Get<std::uint32_t>("the header length");
  if (header_size > reader.remaining())
    reader.Fail("header length " + std::to_string(header_size) + " exceeds the data");
  std::string text(header_size, '\0');
  reader.GetBytes(text.data(), header_size, "the header");
  EditedGarment garment;
  sim::ClothModelData data;
  int num_springs = 0, num_pins = 0, num_triangles = 0;
  bool has_drag = false;
  try {
    const nlohmann::json header = nlohmann::json::parse(text);
    constexpr int kMax = 1 << 26;  // far above any garment; keeps the sizes below sane
    data.name = header.at("name").get<std::string>();
    const int n = Count(header, "num_particles", 1, kMax, reader);
    num_springs = Count(header, "num_springs", 0, kMax, reader);
    num_pins = Count(header, "num_pins", 0, n, reader);
    num_triangles = Count(header, "num_triangles", 0, kMax, reader);
    data.lattice_rows = Count(header, "lattice_rows", 0, kMax, reader);
    data.lattice_cols = Count(header, "lattice_cols", 0, kMax, reader);
    has_drag = header.at("has_drag").get<bool>();
    garment.material = MaterialFromJson(header.at("material"));
    const nlohmann::json& joint = header.at("attached_to");
    if (!joint.is_null()) {
      garment.attached_to = sim::ParseHAnimName(joint.get<std::string>());
      if (!garment.attached_to) {
        reader.Fail("header.attached_to = " + joint.dump() + ": not an H-Anim joint name");
      }
    }
    data.rest_positions.resize(n, 3);
    data.masses.resize(n);
    data.areas.resize(n);
  } catch (const nlohmann::json::exception& error) {
    reader.Fail(std::string("malformed header: ") + error.what());
  }
  const auto n = data.masses.size();
  reader.GetBytes(data.rest_positions.data(), sizeof(double) * 3 * n, "the rest positions");
  ReadDoubles(reader, data.masses, "the masses");
  ReadDoubles(reader, data.areas, "the areas");
  if (has_drag) {
    data.drag.resize(n);
    ReadDoubles(reader, data.drag, "the drag");
  }
  data.springs.resize(num_springs);
  for (sim::Spring& s : data.springs) {
    s.a = reader.Get<std::int32_t>("the springs");
    s.b = reader.Get<std::int32_t>("the springs");
    const auto kind = reader.Get<std::uint8_t>("the springs");
    if (kind > 2) reader.Fail("spring kind " + std::to_string(kind) + ": allowed 0, 1, 2");
    s.kind = static_cast<sim::SpringKind>(kind);
    s.stiffness = reader.Get<double>("the springs");
    s.damping = reader.Get<double>("the springs");
    s.rest_length = reader.Get<double>("the springs");
  }
  data.pinned.resize(num_pins);
  for (int& p : data.pinned) p = reader.Get<std::int32_t>("the pins");
  data.triangles.resize(num_triangles);
  for (Eigen::Vector3i& t : data.triangles) {
    for (int k = 0; k < 3; ++k) t[k] = reader.Get<std::int32_t>("the triangles");
  }
  if (reader.remaining() != 0) {
    reader.Fail(std::to_string(reader.remaining()) + " unexpected bytes after the triangles");
  }
  try {
    garment.model = sim::ClothModel::Create(std::move(data));
  } catch (const sim::InputError& error) {
    reader.Fail(error.what());
  }
  return garment;
}

EditedGarment EditedGarmentFromSimulation(const sim::Simulation& simulation,
                                          const std::string& name) {
  const sim::SceneDescription& scene = simulation.scene();
  const sim::GarmentRange* range = nullptr;
  std::string known;
  for (const sim::GarmentRange& r : simulation.garments()) {
    if (r.name == name) range = &r;
    known += (known.empty() ? "" : ", ") + r.name;
  }
  if (!range) {
    throw sim::InputError(scene.source + ": no garment '" + name + "': the garments are " + known);
  }
  const sim::ClothModel& whole = simulation.model();
  const int first = range->first_particle, count = range->num_particles;
  auto inside = [&](int p) { return p >= first && p < first + count; };
  sim::ClothModelData data;
  data.name = name;
  data.rest_positions = whole.rest_positions().middleRows(first, count);
  data.masses = whole.masses().segment(first, count);
  data.areas = whole.areas().segment(first, count);
  if (whole.drag().size() == whole.num_particles()) data.drag = whole.drag().segment(first, count);
  for (sim::Spring s : whole.springs()) {
    if (!inside(s.a) || !inside(s.b)) continue;
    s.a -= first;
    s.b -= first;
    data.springs.push_back(s);
  }
  for (int p : whole.pinned()) {
    if (inside(p)) data.pinned.push_back(p - first);
  }
  for (int t = range->first_triangle; t < range->first_triangle + range->num_triangles; ++t) {
    data.triangles.push_back(whole.triangles()[t] - Eigen::Vector3i::Constant(first));
  }
  if (simulation.garments().size() == 1) {
    data.lattice_rows = whole.lattice_rows();
    data.lattice_cols = whole.lattice_cols();
  }
  EditedGarment garment;
  garment.model = sim::ClothModel::Create(std::move(data));
  // The joint the garment's attached particles follow, as H-Anim (saved by name, so the
  // garment attaches to any avatar that maps that joint).
  if (const sim::AvatarMotion* avatar = simulation.avatar()) {
    for (const sim::BodyAttachment& a : simulation.attachments()) {
      if (!inside(a.particle)) continue;
      garment.attached_to = avatar->avatar().skeleton().joint(a.joint).hanim;
      break;
    }
  }
  for (const sim::GarmentSpec& spec : scene.garments) {
    if (spec.name != name) continue;
    garment.material = sim::NamedMaterial("stiff_cotton");
    for (const sim::Material& m : scene.materials) {
      if (m.name == spec.material) garment.material = m;
    }
    if (spec.material == "blender_cotton") garment.material = sim::NamedMaterial("blender_cotton");
  }
  return garment;
}

}  // namespace costume::assets
