#include "render/gl_functions.h"

#include <string>

#include "sim_core/common/input_error.h"

namespace costume::render {
namespace {

template <typename Function>
void Load(const GlLoader& loader, const char* name, Function& function) {
  function = reinterpret_cast<Function>(loader(name));
  if (function == nullptr) {
    throw sim::InputError(std::string("OpenGL context: entry point ") + name +
                          " not found (the renderer needs OpenGL 3.3 core)");
  }
}

}  // namespace

GlFunctions LoadGlFunctions(const GlLoader& loader) {
  if (!loader) throw sim::InputError("OpenGL context: empty GL function loader");
  GlFunctions gl;
#define COSTUME_LOAD_GL(name) Load(loader, "gl" #name, gl.name)
  COSTUME_LOAD_GL(GetString);
  COSTUME_LOAD_GL(GetIntegerv);
  COSTUME_LOAD_GL(GetError);
  COSTUME_LOAD_GL(Viewport);
  COSTUME_LOAD_GL(ClearColor);
  COSTUME_LOAD_GL(Clear);
  COSTUME_LOAD_GL(Enable);
  COSTUME_LOAD_GL(Disable);
  COSTUME_LOAD_GL(BlendFuncSeparate);
  COSTUME_LOAD_GL(DepthMask);
  COSTUME_LOAD_GL(CullFace);
  COSTUME_LOAD_GL(Finish);
  COSTUME_LOAD_GL(ReadPixels);
  COSTUME_LOAD_GL(PixelStorei);
  COSTUME_LOAD_GL(CreateShader);
  COSTUME_LOAD_GL(ShaderSource);
  COSTUME_LOAD_GL(CompileShader);
  COSTUME_LOAD_GL(GetShaderiv);
  COSTUME_LOAD_GL(GetShaderInfoLog);
  COSTUME_LOAD_GL(DeleteShader);
  COSTUME_LOAD_GL(CreateProgram);
  COSTUME_LOAD_GL(AttachShader);
  COSTUME_LOAD_GL(BindAttribLocation);
  COSTUME_LOAD_GL(LinkProgram);
  COSTUME_LOAD_GL(GetProgramiv);
  COSTUME_LOAD_GL(GetProgramInfoLog);
  COSTUME_LOAD_GL(DeleteProgram);
  COSTUME_LOAD_GL(UseProgram);
  COSTUME_LOAD_GL(GetUniformLocation);
  COSTUME_LOAD_GL(UniformMatrix4fv);
  COSTUME_LOAD_GL(UniformMatrix3fv);
  COSTUME_LOAD_GL(Uniform3f);
  COSTUME_LOAD_GL(Uniform4f);
  COSTUME_LOAD_GL(Uniform1i);
  COSTUME_LOAD_GL(GenVertexArrays);
  COSTUME_LOAD_GL(BindVertexArray);
  COSTUME_LOAD_GL(DeleteVertexArrays);
  COSTUME_LOAD_GL(GenBuffers);
  COSTUME_LOAD_GL(BindBuffer);
  COSTUME_LOAD_GL(BufferData);
  COSTUME_LOAD_GL(BufferSubData);
  COSTUME_LOAD_GL(DeleteBuffers);
  COSTUME_LOAD_GL(EnableVertexAttribArray);
  COSTUME_LOAD_GL(VertexAttribPointer);
  COSTUME_LOAD_GL(DrawElements);
  COSTUME_LOAD_GL(DrawArrays);
#undef COSTUME_LOAD_GL
  return gl;
}

}  // namespace costume::render
