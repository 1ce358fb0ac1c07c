#include "objscan/render/offscreen_renderer.h"

// The prototypes only give the entry points' types (decltype below): nothing links libOSMesa.
#define GL_GLEXT_PROTOTYPES
#include <GL/osmesa.h>
// osmesa.h brings GL/gl.h; glext.h adds the OpenGL 3.3 entry points, which libOSMesa exports.
#include <GL/glext.h>
#include <dlfcn.h>

#include <array>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <vector>

namespace objscan::render {
namespace {

// libOSMesa is loaded when the first renderer is made, not when objscan starts: with the LLVM
// it brings (llvmpipe), linking it added 80 ms to the start of every command, most of which never
// render. Its entry points are looked up by name in the loaded library. libepoxy, Debian's
// loader of OpenGL entry points, finds them through GLX or EGL only, which OSMesa is not.
// clang-format off
#define OBJSCAN_OSMESA_FUNCTIONS(X)                                                           \
  X(OSMesaCreateContextAttribs) X(OSMesaMakeCurrent) X(OSMesaDestroyContext)                 \
  X(glAttachShader) X(glBindBuffer) X(glBindFramebuffer) X(glBindRenderbuffer)               \
  X(glBindVertexArray) X(glBufferData) X(glCheckFramebufferStatus) X(glClear)                \
  X(glClearBufferfv) X(glClearBufferiv) X(glCompileShader) X(glCreateProgram)                \
  X(glCreateShader) X(glDeleteBuffers) X(glDeleteFramebuffers) X(glDeleteProgram)            \
  X(glDeleteRenderbuffers) X(glDeleteShader) X(glDeleteVertexArrays) X(glDepthFunc)          \
  X(glDisable) X(glDrawBuffers) X(glDrawElements) X(glEnable) X(glEnableVertexAttribArray)   \
  X(glFramebufferRenderbuffer) X(glGenBuffers) X(glGenFramebuffers) X(glGenRenderbuffers)    \
  X(glGenVertexArrays) X(glGetError) X(glGetProgramiv) X(glGetShaderInfoLog)                 \
  X(glGetShaderiv) X(glGetUniformLocation) X(glLinkProgram) X(glPixelStorei) X(glReadBuffer) \
  X(glReadPixels) X(glRenderbufferStorage) X(glShaderSource) X(glUniformMatrix4fv)           \
  X(glUseProgram) X(glVertexAttribIPointer) X(glVertexAttribPointer) X(glViewport)
// clang-format on

// Pointers named as the functions, so that this file's calls reach them: they hide the global
// prototypes here, and a call of an entry point missing from the list fails to link.
#define OBJSCAN_DECLARE(name) decltype(&::name) name = nullptr;
OBJSCAN_OSMESA_FUNCTIONS(OBJSCAN_DECLARE)
#undef OBJSCAN_DECLARE

/// Loads libOSMesa and its entry points once per process; throws when it cannot.
void loadOsMesa() {
  static std::once_flag once;
  static std::string problem;
  std::call_once(once, [] {
    // Never closed: the entry points stay valid for the process's life.
    void* library = dlopen("libOSMesa.so.8", RTLD_NOW | RTLD_LOCAL);
    if (library == nullptr) {
      const char* why = dlerror();
      problem = std::string(
                    "cannot load OSMesa's off-screen OpenGL, libOSMesa.so.8 (is "
                    "libosmesa6 installed?): ") +
                (why ? why : "unknown error");
      return;
    }
#define OBJSCAN_LOAD(name)                                        \
  name = reinterpret_cast<decltype(name)>(dlsym(library, #name)); \
  if (name == nullptr && problem.empty()) problem = "libOSMesa.so.8 has no " #name;
    OBJSCAN_OSMESA_FUNCTIONS(OBJSCAN_LOAD)
#undef OBJSCAN_LOAD
  });
  if (!problem.empty()) throw std::runtime_error(problem);
}

constexpr const char* kVertexShader = R"(#version 330 core
layout(location = 0) in vec3 p_W;
layout(location = 1) in vec3 color;
layout(location = 2) in int label;
uniform mat4 T_C_W;
uniform mat4 projection;
out vec3 p_C;
out vec3 v_color;
flat out int v_label;
void main() {
  vec4 p = T_C_W * vec4(p_W, 1.0);
  p_C = p.xyz;
  v_color = color;
  v_label = label;
  gl_Position = projection * p;
}
)";

// The geometric normal comes from the screen-space derivatives of the camera-frame position,
// which are exact for a planar triangle; it is turned to face the camera.
constexpr const char* kFragmentShader = R"(#version 330 core
in vec3 p_C;
in vec3 v_color;
flat in int v_label;
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_depth;
layout(location = 2) out int out_label;
layout(location = 3) out float out_cos_incidence;
void main() {
  vec3 n = normalize(cross(dFdx(p_C), dFdy(p_C)));
  if (dot(n, p_C) > 0.0) n = -n;
  float cos_incidence = abs(dot(n, normalize(p_C)));
  out_color = vec4(v_color * (0.3 + 0.7 * cos_incidence), 1.0);
  out_depth = p_C.z;
  out_label = v_label;
  out_cos_incidence = cos_incidence;
}
)";

const Rgb8 kDefaultColor(200, 200, 200);

GLuint compile(GLenum kind, const char* source) {
  const GLuint shader = glCreateShader(kind);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    char log[2048] = "";
    glGetShaderInfoLog(shader, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("OpenGL shader does not compile: ") + log);
  }
  return shader;
}

/// Column-major OpenGL projection for pinhole intrinsics, camera frame x right, y down, z forward.
/// Image row v is drawn to framebuffer row v, so glReadPixels returns rows top to bottom in image
/// order; the mirror this implies does not matter because nothing is culled.
std::array<float, 16> projectionMatrix(const Intrinsics& in, float near_m, float far_m) {
  const double w = in.width_px, h = in.height_px, n = near_m, f = far_m;
  std::array<float, 16> m{};
  m[0] = static_cast<float>(2.0 * in.fx_px / w);
  m[5] = static_cast<float>(2.0 * in.fy_px / h);
  m[8] = static_cast<float>((2.0 * in.cx_px + 1.0) / w - 1.0);
  m[9] = static_cast<float>((2.0 * in.cy_px + 1.0) / h - 1.0);
  m[10] = static_cast<float>((f + n) / (f - n));
  m[11] = 1.0f;
  m[14] = static_cast<float>(-2.0 * f * n / (f - n));
  return m;
}

}  // namespace

struct OffscreenRenderer::Impl {
  Intrinsics intrinsics;
  float near_m = 0.1f;
  float far_m = 20.0f;
  OSMesaContext context = nullptr;
  std::vector<unsigned char> default_buffer;
  GLuint program = 0;
  GLuint framebuffer = 0;
  std::array<GLuint, 4> color_targets{};  // colour, depth z, label, cos incidence
  GLuint depth_buffer = 0;
  GLuint vertex_array = 0;
  std::array<GLuint, 4> buffers{};  // positions, colours, labels, indices
  GLsizei index_count = 0;

  void makeCurrent() {
    if (!OSMesaMakeCurrent(context, default_buffer.data(), GL_UNSIGNED_BYTE, intrinsics.width_px,
                           intrinsics.height_px)) {
      throw std::runtime_error("OSMesa cannot make its OpenGL context current");
    }
  }
};

OffscreenRenderer::OffscreenRenderer(const Intrinsics& intrinsics, float near_m, float far_m)
    : impl_(std::make_unique<Impl>()) {
  intrinsics.validate();
  if (!(near_m > 0.0f) || !(far_m > near_m)) {
    throw std::invalid_argument("renderer: need 0 < near_m < far_m");
  }
  Impl& d = *impl_;
  d.intrinsics = intrinsics;
  d.near_m = near_m;
  d.far_m = far_m;
  loadOsMesa();
  const int attributes[] = {OSMESA_FORMAT,
                            OSMESA_RGBA,
                            OSMESA_DEPTH_BITS,
                            0,
                            OSMESA_PROFILE,
                            OSMESA_CORE_PROFILE,
                            OSMESA_CONTEXT_MAJOR_VERSION,
                            3,
                            OSMESA_CONTEXT_MINOR_VERSION,
                            3,
                            0};
  d.context = OSMesaCreateContextAttribs(attributes, nullptr);
  if (d.context == nullptr) {
    throw std::runtime_error(
        "OSMesa cannot create an OpenGL 3.3 core context (is libosmesa6 installed?)");
  }
  const int w = intrinsics.width_px, h = intrinsics.height_px;
  d.default_buffer.assign(static_cast<std::size_t>(w) * h * 4, 0);
  d.makeCurrent();

  d.program = glCreateProgram();
  const GLuint vs = compile(GL_VERTEX_SHADER, kVertexShader);
  const GLuint fs = compile(GL_FRAGMENT_SHADER, kFragmentShader);
  glAttachShader(d.program, vs);
  glAttachShader(d.program, fs);
  glLinkProgram(d.program);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint linked = GL_FALSE;
  glGetProgramiv(d.program, GL_LINK_STATUS, &linked);
  if (linked != GL_TRUE) throw std::runtime_error("OpenGL shader program does not link");

  // One framebuffer with four colour targets and a float depth buffer for the z-test.
  const GLenum formats[4] = {GL_RGBA8, GL_R32F, GL_R32I, GL_R32F};
  glGenFramebuffers(1, &d.framebuffer);
  glBindFramebuffer(GL_FRAMEBUFFER, d.framebuffer);
  glGenRenderbuffers(4, d.color_targets.data());
  for (int i = 0; i < 4; ++i) {
    glBindRenderbuffer(GL_RENDERBUFFER, d.color_targets[i]);
    glRenderbufferStorage(GL_RENDERBUFFER, formats[i], w, h);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + i, GL_RENDERBUFFER,
                              d.color_targets[i]);
  }
  glGenRenderbuffers(1, &d.depth_buffer);
  glBindRenderbuffer(GL_RENDERBUFFER, d.depth_buffer);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, w, h);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, d.depth_buffer);
  const GLenum draw_buffers[4] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2,
                                  GL_COLOR_ATTACHMENT3};
  glDrawBuffers(4, draw_buffers);
  if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
    throw std::runtime_error("OpenGL framebuffer with float/integer targets is not supported here");
  }

  glGenVertexArrays(1, &d.vertex_array);
  glGenBuffers(4, d.buffers.data());
}

OffscreenRenderer::~OffscreenRenderer() {
  if (impl_ && impl_->context != nullptr) {
    Impl& d = *impl_;
    d.makeCurrent();
    glDeleteBuffers(4, d.buffers.data());
    glDeleteVertexArrays(1, &d.vertex_array);
    glDeleteRenderbuffers(4, d.color_targets.data());
    glDeleteRenderbuffers(1, &d.depth_buffer);
    glDeleteFramebuffers(1, &d.framebuffer);
    glDeleteProgram(d.program);
    OSMesaDestroyContext(d.context);
  }
}

const Intrinsics& OffscreenRenderer::intrinsics() const { return impl_->intrinsics; }

void OffscreenRenderer::setMesh(const TriangleMesh& mesh) {
  mesh.validate();
  Impl& d = *impl_;
  d.makeCurrent();
  const std::size_t n = mesh.positions.size();
  std::vector<Rgb8> colors = mesh.colors;
  if (colors.empty()) colors.assign(n, kDefaultColor);
  std::vector<std::int32_t> labels = mesh.labels;
  if (labels.empty()) labels.assign(n, 0);

  glBindVertexArray(d.vertex_array);
  glBindBuffer(GL_ARRAY_BUFFER, d.buffers[0]);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(n * sizeof(Eigen::Vector3f)),
               mesh.positions.data(), GL_STATIC_DRAW);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(Eigen::Vector3f), nullptr);
  glEnableVertexAttribArray(0);
  glBindBuffer(GL_ARRAY_BUFFER, d.buffers[1]);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(n * sizeof(Rgb8)), colors.data(),
               GL_STATIC_DRAW);
  glVertexAttribPointer(1, 3, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(Rgb8), nullptr);
  glEnableVertexAttribArray(1);
  glBindBuffer(GL_ARRAY_BUFFER, d.buffers[2]);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(n * sizeof(std::int32_t)), labels.data(),
               GL_STATIC_DRAW);
  glVertexAttribIPointer(2, 1, GL_INT, sizeof(std::int32_t), nullptr);
  glEnableVertexAttribArray(2);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, d.buffers[3]);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER,
               static_cast<GLsizeiptr>(mesh.triangles.size() * sizeof(Eigen::Vector3i)),
               mesh.triangles.data(), GL_STATIC_DRAW);
  d.index_count = static_cast<GLsizei>(mesh.triangles.size() * 3);
  glBindVertexArray(0);
}

RenderedView OffscreenRenderer::render(const Pose& T_W_C) {
  Impl& d = *impl_;
  d.makeCurrent();
  const int w = d.intrinsics.width_px, h = d.intrinsics.height_px;
  glBindFramebuffer(GL_FRAMEBUFFER, d.framebuffer);
  glViewport(0, 0, w, h);
  glDisable(GL_CULL_FACE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  const GLfloat zero4[4] = {0, 0, 0, 0};
  const GLint zero_int[4] = {0, 0, 0, 0};
  glClearBufferfv(GL_COLOR, 0, zero4);
  glClearBufferfv(GL_COLOR, 1, zero4);
  glClearBufferiv(GL_COLOR, 2, zero_int);
  glClearBufferfv(GL_COLOR, 3, zero4);
  glClear(GL_DEPTH_BUFFER_BIT);

  glUseProgram(d.program);
  const Eigen::Matrix4f T_C_W = T_W_C.inverse().matrix();
  glUniformMatrix4fv(glGetUniformLocation(d.program, "T_C_W"), 1, GL_FALSE, T_C_W.data());
  const std::array<float, 16> projection = projectionMatrix(d.intrinsics, d.near_m, d.far_m);
  glUniformMatrix4fv(glGetUniformLocation(d.program, "projection"), 1, GL_FALSE, projection.data());
  glBindVertexArray(d.vertex_array);
  glDrawElements(GL_TRIANGLES, d.index_count, GL_UNSIGNED_INT, nullptr);
  glBindVertexArray(0);

  RenderedView view;
  cv::Mat rgba(h, w, CV_8UC4);
  view.depth_m.create(h, w, CV_32FC1);
  view.label.create(h, w, CV_32SC1);
  view.cos_incidence.create(h, w, CV_32FC1);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  // RGBA is the target's own layout: read as is, drop alpha on the CPU (faster than GL_RGB).
  glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data);
  cv::cvtColor(rgba, view.color_rgb, cv::COLOR_RGBA2RGB);
  glReadBuffer(GL_COLOR_ATTACHMENT1);
  glReadPixels(0, 0, w, h, GL_RED, GL_FLOAT, view.depth_m.data);
  glReadBuffer(GL_COLOR_ATTACHMENT2);
  glReadPixels(0, 0, w, h, GL_RED_INTEGER, GL_INT, view.label.data);
  glReadBuffer(GL_COLOR_ATTACHMENT3);
  glReadPixels(0, 0, w, h, GL_RED, GL_FLOAT, view.cos_incidence.data);
  if (const GLenum error = glGetError(); error != GL_NO_ERROR) {
    throw std::runtime_error("OpenGL error " + std::to_string(error) + " while rendering");
  }
  return view;
}

}  // namespace objscan::render
