#include "render/scene_renderer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "sim_core/common/input_error.h"

namespace costume::render {
namespace {

constexpr double kPi = 3.14159265358979323846;

// One program draws everything; `mode` picks the shading: 0 lit one-sided, 1 lit two-sided
// (back faces lit with the flipped normal: cloth), 2 the floor grid.
constexpr int kModeOneSided = 0;
constexpr int kModeTwoSided = 1;
constexpr int kModeFloor = 2;

constexpr const char* kVertexShader = R"(#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
uniform mat4 view_projection;
uniform mat4 model;
uniform mat3 normal_matrix;
out vec3 world_position;
out vec3 world_normal;
void main() {
  vec4 p = model * vec4(position, 1.0);
  world_position = p.xyz;
  world_normal = normal_matrix * normal;
  gl_Position = view_projection * p;
}
)";

// A headlight (from the eye) so nothing the camera sees is ever unlit, a key light fixed in
// the world from the upper front left for shape, a little ambient and a soft highlight.
constexpr const char* kFragmentShader = R"(#version 330 core
in vec3 world_position;
in vec3 world_normal;
uniform vec4 colour;
uniform vec3 eye;
uniform vec3 key_direction;
uniform vec3 background;
uniform vec3 floor_centre;
uniform vec3 floor_extent;
uniform int mode;
out vec4 fragment;
void main() {
  if (mode == 2) {
    vec2 cell = world_position.xz / 0.25;
    vec2 distance_to_line = abs(fract(cell - 0.5) - 0.5) / max(fwidth(cell), vec2(1e-6));
    float line = 1.0 - min(min(distance_to_line.x, distance_to_line.y), 1.0);
    vec3 floor_colour = mix(background * 0.9, background * 0.7, line);
    float r = length(world_position.xz - floor_centre.xz) / floor_extent.x;
    fragment = vec4(mix(floor_colour, background, smoothstep(0.6, 1.0, r)), 1.0);
    return;
  }
  vec3 n = normalize(world_normal);
  if (mode == 1 && !gl_FrontFacing) n = -n;
  vec3 to_eye = normalize(eye - world_position);
  float head = max(dot(n, to_eye), 0.0);
  float key = max(dot(n, key_direction), 0.0);
  vec3 half_vector = normalize(to_eye + key_direction);
  float highlight = 0.12 * pow(max(dot(n, half_vector), 0.0), 32.0);
  vec3 lit = colour.rgb * (0.22 + 0.5 * head + 0.4 * key) + vec3(highlight);
  fragment = vec4(min(lit, vec3(1.0)), colour.a);
}
)";

// Interleaved vertex: position then normal, 6 floats.
constexpr int kFloatsPerVertex = 6;

// A vertex array with its buffers and how much they hold.
struct GpuMesh {
  GLuint vao = 0, vbo = 0, ebo = 0;
  std::size_t vertex_capacity = 0;  // floats
  std::size_t index_capacity = 0;   // indices
  GLsizei num_indices = 0;
};

// Geometry as interleaved vertices and triangle indices, built on the CPU.
struct Geometry {
  std::vector<float> vertices;
  std::vector<std::uint32_t> indices;
  void Add(const Eigen::Vector3f& p, const Eigen::Vector3f& n) {
    vertices.insert(vertices.end(), {p.x(), p.y(), p.z(), n.x(), n.y(), n.z()});
  }
  std::uint32_t num_vertices() const {
    return static_cast<std::uint32_t>(vertices.size() / kFloatsPerVertex);
  }
};

// A unit sphere at the origin (latitude-longitude).
Geometry MakeSphere(int slices, int stacks) {
  Geometry g;
  for (int i = 0; i <= stacks; ++i) {
    const double theta = kPi * i / stacks;
    for (int j = 0; j <= slices; ++j) {
      const double phi = 2.0 * kPi * j / slices;
      const Eigen::Vector3f p(std::sin(theta) * std::cos(phi), std::cos(theta),
                              -std::sin(theta) * std::sin(phi));
      g.Add(p, p);
    }
  }
  for (int i = 0; i < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      const std::uint32_t a = i * (slices + 1) + j, b = a + slices + 1;
      g.indices.insert(g.indices.end(), {a, b, a + 1, a + 1, b, b + 1});
    }
  }
  return g;
}

// A cone with its tip at the origin, axis along +z, length 1 and base radius `radius`,
// closed by a base disc.
Geometry MakeCone(int slices, float radius) {
  Geometry g;
  const float slope = radius;  // normal tilt: the side's normal is (cos, sin, -radius)/norm
  for (int j = 0; j <= slices; ++j) {
    const float phi = static_cast<float>(2.0 * kPi * j / slices);
    const Eigen::Vector3f n = Eigen::Vector3f(std::cos(phi), std::sin(phi), -slope).normalized();
    g.Add(Eigen::Vector3f::Zero(), n);
    g.Add(Eigen::Vector3f(radius * std::cos(phi), radius * std::sin(phi), 1.0f), n);
  }
  for (int j = 0; j < slices; ++j) {
    const std::uint32_t tip = 2 * j, base = tip + 1;
    g.indices.insert(g.indices.end(), {tip, base + 2, base});
  }
  const std::uint32_t centre = g.num_vertices();
  g.Add(Eigen::Vector3f(0, 0, 1), Eigen::Vector3f(0, 0, 1));
  for (int j = 0; j <= slices; ++j) {
    const float phi = static_cast<float>(2.0 * kPi * j / slices);
    g.Add(Eigen::Vector3f(radius * std::cos(phi), radius * std::sin(phi), 1.0f),
          Eigen::Vector3f(0, 0, 1));
  }
  for (int j = 0; j < slices; ++j) {
    g.indices.insert(g.indices.end(), {centre, centre + 1 + j, centre + 2 + j});
  }
  return g;
}

// A cube of side 1 centred at the origin with flat faces.
Geometry MakeCube() {
  Geometry g;
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign = -1; sign <= 1; sign += 2) {
      Eigen::Vector3f n = Eigen::Vector3f::Zero();
      n[axis] = static_cast<float>(sign);
      const Eigen::Vector3f u = Eigen::Vector3f::Unit((axis + 1) % 3) * 0.5f;
      const Eigen::Vector3f v = Eigen::Vector3f::Unit((axis + 2) % 3) * 0.5f * sign;
      const Eigen::Vector3f c = n * 0.5f;
      const std::uint32_t first = g.num_vertices();
      g.Add(c - u - v, n);
      g.Add(c + u - v, n);
      g.Add(c + u + v, n);
      g.Add(c - u + v, n);
      g.indices.insert(g.indices.end(), {first, first + 1, first + 2, first, first + 2, first + 3});
    }
  }
  return g;
}

// A square of side 2 in the xz plane, facing +y.
Geometry MakeFloorQuad() {
  Geometry g;
  const Eigen::Vector3f up(0, 1, 0);
  g.Add(Eigen::Vector3f(-1, 0, -1), up);
  g.Add(Eigen::Vector3f(-1, 0, 1), up);
  g.Add(Eigen::Vector3f(1, 0, 1), up);
  g.Add(Eigen::Vector3f(1, 0, -1), up);
  g.indices = {0, 1, 2, 0, 2, 3};
  return g;
}

// Smooth per-vertex normals: the area-weighted sum of the incident triangles' normals.
void ComputeInterleaved(const DrawMesh& mesh, std::vector<Eigen::Vector3f>& normals,
                        std::vector<float>& out) {
  const std::size_t n = mesh.positions.size();
  normals.assign(n, Eigen::Vector3f::Zero());
  for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    const std::uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
    if (a >= n || b >= n || c >= n) continue;
    const Eigen::Vector3f face =
        (mesh.positions[b] - mesh.positions[a]).cross(mesh.positions[c] - mesh.positions[a]);
    normals[a] += face;
    normals[b] += face;
    normals[c] += face;
  }
  out.resize(n * kFloatsPerVertex);
  for (std::size_t i = 0; i < n; ++i) {
    const float length = normals[i].norm();
    const Eigen::Vector3f normal = length > 0.0f ? Eigen::Vector3f(normals[i] / length)
                                                 : Eigen::Vector3f::UnitY();
    float* v = out.data() + i * kFloatsPerVertex;
    v[0] = mesh.positions[i].x();
    v[1] = mesh.positions[i].y();
    v[2] = mesh.positions[i].z();
    v[3] = normal.x();
    v[4] = normal.y();
    v[5] = normal.z();
  }
}

// Parses "major.minor" at the start of a GL_VERSION string; {0, 0} if it is not there
// (an OpenGL ES string starts with "OpenGL ES", which this renderer does not support).
std::pair<int, int> ParseVersion(const char* version) {
  int major = 0, minor = 0;
  if (version == nullptr || std::sscanf(version, "%d.%d", &major, &minor) != 2) return {0, 0};
  return {major, minor};
}

}  // namespace

struct SceneRenderer::Impl {
  GlFunctions gl;
  std::string version;
  GLuint program = 0;
  struct {
    GLint view_projection, model, normal_matrix, colour, eye, key_direction, background,
        floor_centre, floor_extent, mode;
  } uniform{};
  GpuMesh sphere, cone, cube, floor_quad;
  std::vector<GpuMesh> meshes;
  // Scratch reused between frames.
  std::vector<Eigen::Vector3f> normals;
  std::vector<float> interleaved;

  GLuint Compile(GLenum type, const char* source);
  void BuildProgram();
  GpuMesh CreateMesh();
  void Upload(GpuMesh& mesh, const std::vector<float>& vertices,
              const std::vector<std::uint32_t>& indices);
  GpuMesh MakeStatic(const Geometry& geometry);
  void Destroy(GpuMesh& mesh);
  void SetModel(const Eigen::Matrix4f& model);
  void DrawIndexed(const GpuMesh& mesh);
  void DrawFloor(const RenderScene& scene);
  void DrawCursor(const render::DrawCursor& cursor);
};

GLuint SceneRenderer::Impl::Compile(GLenum type, const char* source) {
  const GLuint shader = gl.CreateShader(type);
  gl.ShaderSource(shader, 1, &source, nullptr);
  gl.CompileShader(shader);
  GLint ok = 0;
  gl.GetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl.GetShaderInfoLog(shader, sizeof(log), nullptr, log);
    gl.DeleteShader(shader);
    throw sim::InputError("SceneRenderer: shader does not compile on OpenGL " + version + ": " +
                          log);
  }
  return shader;
}

void SceneRenderer::Impl::BuildProgram() {
  const GLuint vertex = Compile(GL_VERTEX_SHADER, kVertexShader);
  const GLuint fragment = Compile(GL_FRAGMENT_SHADER, kFragmentShader);
  program = gl.CreateProgram();
  gl.AttachShader(program, vertex);
  gl.AttachShader(program, fragment);
  gl.LinkProgram(program);
  gl.DeleteShader(vertex);
  gl.DeleteShader(fragment);
  GLint ok = 0;
  gl.GetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl.GetProgramInfoLog(program, sizeof(log), nullptr, log);
    throw sim::InputError("SceneRenderer: shader program does not link on OpenGL " + version +
                          ": " + log);
  }
  const auto location = [&](const char* name) { return gl.GetUniformLocation(program, name); };
  uniform.view_projection = location("view_projection");
  uniform.model = location("model");
  uniform.normal_matrix = location("normal_matrix");
  uniform.colour = location("colour");
  uniform.eye = location("eye");
  uniform.key_direction = location("key_direction");
  uniform.background = location("background");
  uniform.floor_centre = location("floor_centre");
  uniform.floor_extent = location("floor_extent");
  uniform.mode = location("mode");
}

GpuMesh SceneRenderer::Impl::CreateMesh() {
  GpuMesh mesh;
  gl.GenVertexArrays(1, &mesh.vao);
  gl.GenBuffers(1, &mesh.vbo);
  gl.GenBuffers(1, &mesh.ebo);
  gl.BindVertexArray(mesh.vao);
  gl.BindBuffer(GL_ARRAY_BUFFER, mesh.vbo);
  gl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, mesh.ebo);
  const GLsizei stride = kFloatsPerVertex * sizeof(float);
  gl.EnableVertexAttribArray(0);
  gl.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride, nullptr);
  gl.EnableVertexAttribArray(1);
  gl.VertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride,
                         reinterpret_cast<const void*>(3 * sizeof(float)));
  gl.BindVertexArray(0);
  return mesh;
}

// Re-specifies a buffer only when it must grow (by half again, so a growing cloth does not
// reallocate every frame); otherwise overwrites it in place.
void SceneRenderer::Impl::Upload(GpuMesh& mesh, const std::vector<float>& vertices,
                                 const std::vector<std::uint32_t>& indices) {
  gl.BindVertexArray(mesh.vao);
  gl.BindBuffer(GL_ARRAY_BUFFER, mesh.vbo);
  if (vertices.size() > mesh.vertex_capacity) {
    mesh.vertex_capacity = vertices.size() + vertices.size() / 2;
    gl.BufferData(GL_ARRAY_BUFFER, mesh.vertex_capacity * sizeof(float), nullptr, GL_DYNAMIC_DRAW);
  }
  gl.BufferSubData(GL_ARRAY_BUFFER, 0, vertices.size() * sizeof(float), vertices.data());
  if (indices.size() > mesh.index_capacity) {
    mesh.index_capacity = indices.size() + indices.size() / 2;
    gl.BufferData(GL_ELEMENT_ARRAY_BUFFER, mesh.index_capacity * sizeof(std::uint32_t), nullptr,
                  GL_DYNAMIC_DRAW);
  }
  gl.BufferSubData(GL_ELEMENT_ARRAY_BUFFER, 0, indices.size() * sizeof(std::uint32_t),
                   indices.data());
  mesh.num_indices = static_cast<GLsizei>(indices.size());
  gl.BindVertexArray(0);
}

GpuMesh SceneRenderer::Impl::MakeStatic(const Geometry& geometry) {
  GpuMesh mesh = CreateMesh();
  Upload(mesh, geometry.vertices, geometry.indices);
  return mesh;
}

void SceneRenderer::Impl::Destroy(GpuMesh& mesh) {
  gl.DeleteVertexArrays(1, &mesh.vao);
  gl.DeleteBuffers(1, &mesh.vbo);
  gl.DeleteBuffers(1, &mesh.ebo);
  mesh = GpuMesh{};
}

void SceneRenderer::Impl::SetModel(const Eigen::Matrix4f& model) {
  const Eigen::Matrix3f normal_matrix = model.topLeftCorner<3, 3>().inverse().transpose();
  gl.UniformMatrix4fv(uniform.model, 1, GL_FALSE, model.data());
  gl.UniformMatrix3fv(uniform.normal_matrix, 1, GL_FALSE, normal_matrix.data());
}

void SceneRenderer::Impl::DrawIndexed(const GpuMesh& mesh) {
  if (mesh.num_indices == 0) return;
  gl.BindVertexArray(mesh.vao);
  gl.DrawElements(GL_TRIANGLES, mesh.num_indices, GL_UNSIGNED_INT, nullptr);
}

// The floor under the meshes' footprint, a metre wider all round, fading into the background.
void SceneRenderer::Impl::DrawFloor(const RenderScene& scene) {
  Eigen::AlignedBox3f box;
  for (const DrawMesh& mesh : scene.meshes) {
    for (const Eigen::Vector3f& p : mesh.positions) box.extend(p);
  }
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  float extent = 3.0f;
  if (!box.isEmpty()) {
    centre = box.center();
    extent = std::max(2.0f, 0.5f * Eigen::Vector2f(box.sizes().x(), box.sizes().z()).norm() + 1.0f);
  }
  centre.y() = scene.floor_height;
  Eigen::Matrix4f model = Eigen::Matrix4f::Identity();
  model.diagonal().head<3>().setConstant(extent);
  model.topRightCorner<3, 1>() = centre;
  SetModel(model);
  gl.Uniform1i(uniform.mode, kModeFloor);
  gl.Uniform3f(uniform.floor_centre, centre.x(), centre.y(), centre.z());
  gl.Uniform3f(uniform.floor_extent, extent, extent, extent);
  DrawIndexed(floor_quad);
}

void SceneRenderer::Impl::DrawCursor(const render::DrawCursor& cursor) {
  const Eigen::Affine3f pose = (Eigen::Translation3d(cursor.position) *
                                cursor.orientation.normalized()).cast<float>();
  const float s = static_cast<float>(cursor.size);
  gl.Uniform1i(uniform.mode, kModeOneSided);
  gl.Uniform4f(uniform.colour, 0.85f, 0.22f, 0.18f, 1.0f);
  if (cursor.shape == CursorShape::kCone) {
    // Tip at the position, pointing along -z: the unit cone (tip at origin, along +z) as is.
    SetModel((pose * Eigen::Scaling(s)).matrix());
    DrawIndexed(cone);
    return;
  }
  // A hand: palm box, four fingers along -z and a thumb to the side, sized by `size`.
  const auto box = [&](const Eigen::Vector3f& centre, const Eigen::Vector3f& sizes, float yaw) {
    const Eigen::Affine3f local = Eigen::Translation3f(centre * s) *
                                  Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitY()) *
                                  Eigen::Scaling(Eigen::Vector3f(sizes * s));
    SetModel((pose * local).matrix());
    DrawIndexed(cube);
  };
  box(Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(0.45f, 0.12f, 0.5f), 0.0f);
  for (int finger = 0; finger < 4; ++finger) {
    const float x = -0.165f + 0.11f * finger;
    const float length = finger == 0 || finger == 3 ? 0.36f : 0.45f;
    box(Eigen::Vector3f(x, 0, -0.25f - 0.5f * length), Eigen::Vector3f(0.09f, 0.09f, length), 0.0f);
  }
  box(Eigen::Vector3f(0.3f, 0, -0.12f), Eigen::Vector3f(0.09f, 0.09f, 0.3f), 0.6f);
}

SceneRenderer::SceneRenderer(const GlLoader& loader) : impl_(std::make_unique<Impl>()) {
  if (!loader) throw sim::InputError("SceneRenderer: empty GL function loader");
  auto get_string = reinterpret_cast<PFNGLGETSTRINGPROC>(loader("glGetString"));
  const char* version =
      get_string != nullptr ? reinterpret_cast<const char*>(get_string(GL_VERSION)) : nullptr;
  if (version == nullptr) {
    throw sim::InputError("SceneRenderer: no current OpenGL context (glGetString(GL_VERSION) "
                          "returned nothing); the renderer needs OpenGL 3.3 core");
  }
  impl_->version = version;
  const auto [major, minor] = ParseVersion(version);
  if (major < 3 || (major == 3 && minor < 3)) {
    throw sim::InputError("SceneRenderer: OpenGL version = '" + impl_->version +
                          "': the renderer needs OpenGL 3.3 core or newer");
  }
  impl_->gl = LoadGlFunctions(loader);
  impl_->BuildProgram();
  impl_->sphere = impl_->MakeStatic(MakeSphere(32, 16));
  impl_->cone = impl_->MakeStatic(MakeCone(24, 0.3f));
  impl_->cube = impl_->MakeStatic(MakeCube());
  impl_->floor_quad = impl_->MakeStatic(MakeFloorQuad());
}

SceneRenderer::~SceneRenderer() {
  if (!impl_ || impl_->program == 0) return;
  for (GpuMesh& mesh : impl_->meshes) impl_->Destroy(mesh);
  for (GpuMesh* mesh : {&impl_->sphere, &impl_->cone, &impl_->cube, &impl_->floor_quad}) {
    impl_->Destroy(*mesh);
  }
  impl_->gl.DeleteProgram(impl_->program);
}

const char* SceneRenderer::GlVersion() const { return impl_->version.c_str(); }

void SceneRenderer::Draw(const RenderScene& scene, const Camera& camera, int width, int height) {
  if (width <= 0 || height <= 0) return;
  Impl& r = *impl_;
  const GlFunctions& gl = r.gl;
  gl.Viewport(0, 0, width, height);
  gl.ClearColor(scene.background.x(), scene.background.y(), scene.background.z(), 1.0f);
  gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  gl.Enable(GL_DEPTH_TEST);
  gl.Disable(GL_BLEND);
  gl.Disable(GL_CULL_FACE);
  gl.DepthMask(GL_TRUE);

  gl.UseProgram(r.program);
  const Eigen::Matrix4f view_projection =
      camera.ViewProjection(static_cast<double>(width) / height).cast<float>();
  gl.UniformMatrix4fv(r.uniform.view_projection, 1, GL_FALSE, view_projection.data());
  gl.Uniform3f(r.uniform.eye, camera.eye.x(), camera.eye.y(), camera.eye.z());
  const Eigen::Vector3f key = Eigen::Vector3f(-0.4f, 0.8f, 0.6f).normalized();
  gl.Uniform3f(r.uniform.key_direction, key.x(), key.y(), key.z());
  gl.Uniform3f(r.uniform.background, scene.background.x(), scene.background.y(),
               scene.background.z());

  if (scene.floor) r.DrawFloor(scene);

  r.SetModel(Eigen::Matrix4f::Identity());
  while (r.meshes.size() < scene.meshes.size()) r.meshes.push_back(r.CreateMesh());
  for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
    const DrawMesh& mesh = scene.meshes[i];
    ComputeInterleaved(mesh, r.normals, r.interleaved);
    r.Upload(r.meshes[i], r.interleaved, mesh.indices);
    gl.Uniform1i(r.uniform.mode, mesh.two_sided ? kModeTwoSided : kModeOneSided);
    gl.Uniform4f(r.uniform.colour, mesh.colour.x(), mesh.colour.y(), mesh.colour.z(), 1.0f);
    r.DrawIndexed(r.meshes[i]);
  }

  if (scene.cursor) r.DrawCursor(*scene.cursor);

  if (scene.selection) {
    // Last and blended, not writing depth: the cloth inside stays visible through it. Only
    // its front faces, so it is tinted once. Destination alpha stays 1 (opaque images).
    const DrawSphere& sphere = *scene.selection;
    gl.Enable(GL_BLEND);
    gl.BlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
    gl.DepthMask(GL_FALSE);
    gl.Enable(GL_CULL_FACE);
    gl.CullFace(GL_BACK);
    Eigen::Matrix4f model = Eigen::Matrix4f::Identity();
    model.diagonal().head<3>().setConstant(static_cast<float>(sphere.radius));
    model.topRightCorner<3, 1>() = sphere.centre.cast<float>();
    r.SetModel(model);
    gl.Uniform1i(r.uniform.mode, kModeOneSided);
    gl.Uniform4f(r.uniform.colour, sphere.colour[0], sphere.colour[1], sphere.colour[2],
                 sphere.colour[3]);
    r.DrawIndexed(r.sphere);
    gl.Disable(GL_CULL_FACE);
    gl.DepthMask(GL_TRUE);
    gl.Disable(GL_BLEND);
  }
  gl.BindVertexArray(0);
  gl.UseProgram(0);
}

}  // namespace costume::render
