#include "test_support.h"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <chrono>
#include <optional>

#include <gtest/gtest.h>

#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <stdexcept>

#include "objscan/core/error.h"

extern char** environ;

namespace objscan::testing {
namespace fs = std::filesystem;

TempDir::TempDir() {
  std::string tmpl = (fs::temp_directory_path() / "objscan-test-XXXXXX").string();
  if (::mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  path_ = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

void writeBytes(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

std::size_t entryCount(const fs::path& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

FileSizeLimit::FileSizeLimit(std::uint64_t bytes) {
  struct rlimit limit {};
  if (::getrlimit(RLIMIT_FSIZE, &limit) != 0) throw std::runtime_error("getrlimit failed");
  saved_soft_limit_ = limit.rlim_cur;
  saved_handler_ = std::signal(SIGXFSZ, SIG_IGN);
  limit.rlim_cur = bytes;
  if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) throw std::runtime_error("setrlimit failed");
}

FileSizeLimit::~FileSizeLimit() {
  struct rlimit limit {};
  ::getrlimit(RLIMIT_FSIZE, &limit);
  limit.rlim_cur = saved_soft_limit_;
  ::setrlimit(RLIMIT_FSIZE, &limit);
  std::signal(SIGXFSZ, saved_handler_);
}

std::string readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

Intrinsics centredCamera(int width, int height, double focal_px) {
  Intrinsics in;
  in.width_px = width;
  in.height_px = height;
  in.fx_px = in.fy_px = focal_px;
  in.cx_px = (width - 1) / 2.0;
  in.cy_px = (height - 1) / 2.0;
  return in;
}

TriangleMesh makeCube(float side_m) {
  TriangleMesh m;
  const float h = side_m / 2;
  for (int i = 0; i < 8; ++i) {
    m.positions.emplace_back((i & 1) ? h : -h, (i & 2) ? h : -h, (i & 4) ? h : -h);
  }
  // Two triangles per face, counter-clockwise seen from outside.
  const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : faces) {
    m.triangles.emplace_back(f[0], f[1], f[2]);
    m.triangles.emplace_back(f[0], f[2], f[3]);
  }
  return m;
}

TriangleMesh makeHeightField(int n, float half, const std::function<float(float, float)>& f) {
  TriangleMesh mesh;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const float x = -half + 2.0f * half * static_cast<float>(i) / static_cast<float>(n - 1);
      const float y = -half + 2.0f * half * static_cast<float>(j) / static_cast<float>(n - 1);
      mesh.positions.emplace_back(x, y, f(x, y));
    }
  }
  addGridTriangles(mesh, n, n);
  mesh.computeNormals();
  return mesh;
}

void addGridTriangles(TriangleMesh& mesh, int rows, int n) {
  for (int j = 0; j + 1 < rows; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int v = j * n + i;
      mesh.triangles.emplace_back(v, v + 1, v + n + 1);
      mesh.triangles.emplace_back(v, v + n + 1, v + n);
    }
  }
}

TriangleMesh makeRandomMesh(std::uint32_t seed, std::size_t vertices, std::size_t triangles,
                            bool with_normals, bool with_colors) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> coord(-5.0f, 5.0f);
  const float awkward[] = {0.0f,    -0.0f,        1e-38f, 1.4e-45f /* subnormal */,
                           3.4e38f, -123456.789f, 0.1f,   1.0f / 3.0f};
  TriangleMesh m;
  for (std::size_t i = 0; i < vertices; ++i) {
    Eigen::Vector3f p(coord(rng), coord(rng), coord(rng));
    if (i < std::size(awkward)) p.x() = awkward[i];
    m.positions.push_back(p);
    if (with_normals)
      m.normals.push_back(Eigen::Vector3f(coord(rng), coord(rng), coord(rng) + 11.0f).normalized());
    if (with_colors) m.colors.emplace_back(rng() & 255, rng() & 255, rng() & 255);
    if (with_colors) m.labels.push_back(static_cast<std::int32_t>(rng() % 7) - 1);  // -1..5
  }
  std::uniform_int_distribution<int> index(0, static_cast<int>(vertices) - 1);
  while (m.triangles.size() < triangles) {
    const Eigen::Vector3i t(index(rng), index(rng), index(rng));
    if (t[0] != t[1] && t[1] != t[2] && t[0] != t[2]) m.triangles.push_back(t);
  }
  return m;
}

bool bitwiseEqual(const TriangleMesh& a, const TriangleMesh& b) {
  auto same = [](const std::vector<Eigen::Vector3f>& x, const std::vector<Eigen::Vector3f>& y) {
    return x.size() == y.size() &&
           (x.empty() || std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) == 0);
  };
  const bool same_weights =
      a.weights.size() == b.weights.size() &&
      (a.weights.empty() ||
       std::memcmp(a.weights.data(), b.weights.data(), a.weights.size() * sizeof(float)) == 0);
  return same(a.positions, b.positions) && same(a.normals, b.normals) && a.colors == b.colors &&
         a.labels == b.labels && same_weights && a.ignore == b.ignore && a.triangles == b.triangles;
}

void expectInputError(const std::function<void()>& action, const fs::path& path,
                      const std::string& needle) {
  try {
    action();
    ADD_FAILURE() << "no error for " << path << "; expected one containing: " << needle;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(path.string() + ": ", 0), 0u) << what;
    EXPECT_NE(what.find(needle), std::string::npos)
        << "message: " << what << "\nexpected to contain: " << needle;
  }
}

ProcessResult runProcess(const std::vector<std::string>& argv) { return runProcess(argv, {}); }

ProcessResult runProcess(const std::vector<std::string>& argv, const ProcessOptions& options) {
  int out_pipe[2], err_pipe[2];
  if (::pipe2(out_pipe, O_CLOEXEC) != 0 || ::pipe2(err_pipe, O_CLOEXEC) != 0)
    throw std::runtime_error("pipe failed");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, out_pipe[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, err_pipe[1], STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  if (!options.cwd.empty()) posix_spawn_file_actions_addchdir_np(&actions, options.cwd.c_str());
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  std::vector<char*> env;
  for (char** e = environ; *e != nullptr; ++e) env.push_back(*e);
  for (const auto& e : options.env) env.push_back(const_cast<char*>(e.c_str()));
  env.push_back(nullptr);
  const int rc = ::posix_spawn(&pid, args[0], &actions, nullptr, args.data(), env.data());
  posix_spawn_file_actions_destroy(&actions);
  ::close(out_pipe[1]);
  ::close(err_pipe[1]);
  if (rc != 0) throw std::runtime_error("cannot start " + argv[0] + ": " + std::strerror(rc));

  ProcessResult result;
  pollfd fds[2] = {{out_pipe[0], POLLIN, 0}, {err_pipe[0], POLLIN, 0}};
  std::string* sinks[2] = {&result.out, &result.err};
  int open_fds = 2;
  bool signal_sent = options.signal == 0;
  std::optional<std::chrono::steady_clock::time_point> signal_at;
  while (open_fds > 0) {
    int timeout_ms = -1;
    if (!signal_sent && !signal_at && result.err.find(options.signal_when) != std::string::npos) {
      signal_at =
          std::chrono::steady_clock::now() + std::chrono::milliseconds(options.signal_delay_ms);
    }
    if (!signal_sent && signal_at) {
      const auto now = std::chrono::steady_clock::now();
      if (now >= *signal_at) {
        ::kill(pid, options.signal);
        signal_sent = true;
      } else {
        timeout_ms = static_cast<int>(
            std::chrono::duration_cast<std::chrono::milliseconds>(*signal_at - now).count() + 1);
      }
    }
    const int ready = ::poll(fds, 2, timeout_ms);
    if (ready < 0) break;
    if (ready == 0) continue;
    for (int i = 0; i < 2; ++i) {
      if (fds[i].fd < 0 || !(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      char buf[4096];
      const ssize_t n = ::read(fds[i].fd, buf, sizeof buf);
      if (n > 0) {
        sinks[i]->append(buf, static_cast<std::size_t>(n));
      } else {
        ::close(fds[i].fd);
        fds[i].fd = -1;
        --open_fds;
      }
    }
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

std::string sevenScenesFrameName(int number, const std::string& suffix) {
  char name[64];
  std::snprintf(name, sizeof name, "frame-%06d.%s", number, suffix.c_str());
  return name;
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) eol = text.size();
    out.push_back(text.substr(pos, eol - pos));
    pos = eol + 1;
  }
  return out;
}

}  // namespace objscan::testing
