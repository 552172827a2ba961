#pragma once
/// @file
/// The OpenGL 3.3 core entry points the renderer uses, fetched through a loader function so
/// that one renderer serves both OSMesa (OSMesaGetProcAddress) and Qt
/// (QOpenGLContext::getProcAddress). Calling libGL's exported symbols directly would get no
/// context under OSMesa (docs/rendering.md), so nothing here links libGL.

#include <functional>

#include <GL/glcorearb.h>

namespace costume::render {

/// Returns the address of a GL entry point by name (e.g. "glDrawElements"), or nullptr when the
/// current context does not provide it. Must be called with the target context current.
using GlLoader = std::function<void*(const char*)>;

/// The GL 3.3 core functions the renderer calls, as function pointers of the current context.
/// Filled by LoadGlFunctions; a pointer is never null after a successful load.
struct GlFunctions {
  PFNGLGETSTRINGPROC GetString = nullptr;
  PFNGLGETINTEGERVPROC GetIntegerv = nullptr;
  PFNGLGETERRORPROC GetError = nullptr;
  PFNGLVIEWPORTPROC Viewport = nullptr;
  PFNGLCLEARCOLORPROC ClearColor = nullptr;
  PFNGLCLEARPROC Clear = nullptr;
  PFNGLENABLEPROC Enable = nullptr;
  PFNGLDISABLEPROC Disable = nullptr;
  PFNGLBLENDFUNCSEPARATEPROC BlendFuncSeparate = nullptr;
  PFNGLDEPTHMASKPROC DepthMask = nullptr;
  PFNGLCULLFACEPROC CullFace = nullptr;
  PFNGLFINISHPROC Finish = nullptr;
  PFNGLREADPIXELSPROC ReadPixels = nullptr;
  PFNGLPIXELSTOREIPROC PixelStorei = nullptr;

  PFNGLCREATESHADERPROC CreateShader = nullptr;
  PFNGLSHADERSOURCEPROC ShaderSource = nullptr;
  PFNGLCOMPILESHADERPROC CompileShader = nullptr;
  PFNGLGETSHADERIVPROC GetShaderiv = nullptr;
  PFNGLGETSHADERINFOLOGPROC GetShaderInfoLog = nullptr;
  PFNGLDELETESHADERPROC DeleteShader = nullptr;
  PFNGLCREATEPROGRAMPROC CreateProgram = nullptr;
  PFNGLATTACHSHADERPROC AttachShader = nullptr;
  PFNGLBINDATTRIBLOCATIONPROC BindAttribLocation = nullptr;
  PFNGLLINKPROGRAMPROC LinkProgram = nullptr;
  PFNGLGETPROGRAMIVPROC GetProgramiv = nullptr;
  PFNGLGETPROGRAMINFOLOGPROC GetProgramInfoLog = nullptr;
  PFNGLDELETEPROGRAMPROC DeleteProgram = nullptr;
  PFNGLUSEPROGRAMPROC UseProgram = nullptr;
  PFNGLGETUNIFORMLOCATIONPROC GetUniformLocation = nullptr;
  PFNGLUNIFORMMATRIX4FVPROC UniformMatrix4fv = nullptr;
  PFNGLUNIFORMMATRIX3FVPROC UniformMatrix3fv = nullptr;
  PFNGLUNIFORM3FPROC Uniform3f = nullptr;
  PFNGLUNIFORM4FPROC Uniform4f = nullptr;
  PFNGLUNIFORM1IPROC Uniform1i = nullptr;

  PFNGLGENVERTEXARRAYSPROC GenVertexArrays = nullptr;
  PFNGLBINDVERTEXARRAYPROC BindVertexArray = nullptr;
  PFNGLDELETEVERTEXARRAYSPROC DeleteVertexArrays = nullptr;
  PFNGLGENBUFFERSPROC GenBuffers = nullptr;
  PFNGLBINDBUFFERPROC BindBuffer = nullptr;
  PFNGLBUFFERDATAPROC BufferData = nullptr;
  PFNGLBUFFERSUBDATAPROC BufferSubData = nullptr;
  PFNGLDELETEBUFFERSPROC DeleteBuffers = nullptr;
  PFNGLENABLEVERTEXATTRIBARRAYPROC EnableVertexAttribArray = nullptr;
  PFNGLVERTEXATTRIBPOINTERPROC VertexAttribPointer = nullptr;
  PFNGLDRAWELEMENTSPROC DrawElements = nullptr;
  PFNGLDRAWARRAYSPROC DrawArrays = nullptr;
};

/// Fetches every entry point of GlFunctions through `loader` (the context must be current).
/// Throws sim::InputError naming the first missing function.
GlFunctions LoadGlFunctions(const GlLoader& loader);

}  // namespace costume::render
