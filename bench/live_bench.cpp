// What the live page costs the scan: objscan fuse on the same frames without --serve, with the
// server and no client, with several clients following the page as fast as it lets them, and
// with online discovery on top; frames/s of each and its ratio to the run without --serve.
//
//   live_bench [--folder DIR] [--frames N] [--clients C] [--sensor] [--repeat R]
//
// DIR defaults to <data>/7scenes_300, N to 150, C to 4, R to 2 (the median is shown). A client
// does what the page does: /api/state?after=N (long polling), then the model and colour
// pictures, in a loop. With --sensor the frames come from the virtual OpenNI2 sensor at 30 Hz
// (virtual:DIR?fps=30) instead of the folder, and the table shows the frames the sensor
// delivered that fusion missed (dropped): the live case, where the scan must keep the sensor's
// rate. Without it fusion runs as fast as it can, so any CPU the server takes shows as frames/s.

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <civetweb.h>

#include "bench_main.h"
#include "build_paths.h"

extern char** environ;

namespace fs = std::filesystem;

namespace {

struct Run {
  double frames_per_s = 0.0;
  std::size_t read = 0;
  std::size_t requests = 0;  ///< answered to the clients
};

/// One GET through civetweb's client; the body's size, or -1.
long long fetch(int port, const std::string& target) {
  char error[128] = "";
  mg_connection* conn = mg_download("127.0.0.1", port, 0, error, sizeof error,
                                    "GET %s HTTP/1.0\r\nHost: 127.0.0.1:%d\r\n\r\n", target.c_str(),
                                    port);
  if (!conn) return -1;
  const mg_response_info* info = mg_get_response_info(conn);
  const bool ok = info && info->status_code == 200;
  long long size = 0;
  char buffer[16384];
  for (int n; (n = mg_read(conn, buffer, sizeof buffer)) > 0;) size += n;
  mg_close_connection(conn);
  return ok ? size : -1;
}

/// The "after" of the next long poll: the seq of a state answer; `final` set once the state is
/// the run's last (the page stops asking then); `after` itself when the request failed.
std::uint64_t seqOf(int port, std::uint64_t after, bool* final) {
  char error[128] = "";
  mg_connection* conn = mg_download("127.0.0.1", port, 0, error, sizeof error,
                                    "GET /api/state?after=%llu HTTP/1.0\r\nHost: 127.0.0.1:%d\r\n\r\n",
                                    static_cast<unsigned long long>(after), port);
  if (!conn) return after;
  std::string body;
  char buffer[16384];
  for (int n; (n = mg_read(conn, buffer, sizeof buffer)) > 0;) body.append(buffer, static_cast<std::size_t>(n));
  mg_close_connection(conn);
  *final = body.find("\"final\":{") != std::string::npos;
  const std::size_t at = body.find("\"seq\":");
  return at == std::string::npos ? after : std::strtoull(body.c_str() + at + 6, nullptr, 10);
}

/// Runs objscan with `args`; with `clients`, that many page-like clients follow its live page
/// until it ends.
Run runObjscan(std::vector<std::string> args, int clients) {
  int out_pipe[2];
  if (::pipe2(out_pipe, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, out_pipe[1], STDOUT_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  args.insert(args.begin(), OBJSCAN_EXE);
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ) != 0) {
    throw std::runtime_error(std::string("cannot run ") + OBJSCAN_EXE);
  }
  posix_spawn_file_actions_destroy(&actions);
  ::close(out_pipe[1]);
  std::string out;
  std::atomic<bool> done{false};
  std::atomic<std::size_t> requests{0};
  std::vector<std::thread> threads;
  char buffer[4096];
  for (ssize_t n; (n = ::read(out_pipe[0], buffer, sizeof buffer)) > 0;) {
    out.append(buffer, static_cast<std::size_t>(n));
    const std::size_t line = out.find("live page     http://127.0.0.1:");
    if (threads.empty() && clients > 0 && line != std::string::npos &&
        out.find('\n', line) != std::string::npos) {
      const int port = std::atoi(out.c_str() + line + 31);
      for (int c = 0; c < clients; ++c) {
        threads.emplace_back([port, &done, &requests] {
          std::uint64_t after = 0;
          bool final = false;
          while (!done.load() && !final) {
            const std::uint64_t seq = seqOf(port, after, &final);
            if (seq == after) {  // no answer, or nothing new: as the page, ask again later
              std::this_thread::sleep_for(std::chrono::milliseconds(100));
              continue;
            }
            after = seq;
            fetch(port, "/api/model.jpg?p=" + std::to_string(after));
            fetch(port, "/api/color.jpg?p=" + std::to_string(after));
            requests += 3;
          }
        });
      }
    }
  }
  ::close(out_pipe[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  done = true;
  for (std::thread& t : threads) t.join();
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw std::runtime_error("objscan failed:\n" + out);
  }
  Run run;
  const std::size_t rate = out.find(" frames/s;");
  const std::size_t open = out.rfind('(', rate);
  if (rate == std::string::npos || open == std::string::npos) {
    throw std::runtime_error("no frames/s in objscan's output:\n" + out);
  }
  run.frames_per_s = std::atof(out.c_str() + open + 1);
  const std::size_t frames = out.find("\nframes        ");
  if (frames != std::string::npos) run.read = std::strtoul(out.c_str() + frames + 15, nullptr, 10);
  run.requests = requests.load();
  return run;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

int run(int argc, char** argv) {
  fs::path folder = fs::path(OBJSCAN_DATA_DIR) / "7scenes_300";
  int frames = 150, clients = 4, repeat = 2;  // --frames: without --sensor
  bool sensor = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&] {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return std::string(argv[++i]);
    };
    if (a == "--folder") folder = value();
    else if (a == "--frames") frames = std::stoi(value());
    else if (a == "--clients") clients = std::stoi(value());
    else if (a == "--repeat") repeat = std::max(1, std::stoi(value()));
    else if (a == "--sensor") sensor = true;
    else throw std::invalid_argument("unknown option " + a + " (see the comment at the top)");
  }
  mg_init_library(0);
  const fs::path out = fs::temp_directory_path() / ("objscan-live-bench-" + std::to_string(::getpid()));
  const std::string source = sensor ? "virtual:" + folder.string() + "?fps=30" : folder.string();
  std::vector<std::string> base = {"fuse", source, "--out", out.string()};
  std::size_t delivered = 0;  // with --sensor: the frames the sensor sends (its folder's)
  if (sensor) {
    for (const auto& e : fs::recursive_directory_iterator(folder)) {
      const std::string name = e.path().filename().string();
      delivered += name.size() > 9 && name.ends_with("depth.png") ? 1 : 0;
    }
  } else {
    base.insert(base.end(), {"--end", std::to_string(frames)});
  }
  struct Case {
    const char* name;
    std::vector<std::string> extra;
    int clients;
  };
  const std::vector<Case> cases = {
      {"no --serve", {}, 0},
      {"--serve, no client", {"--serve", "0", "--serve-wait", "0", "--no-live-discovery"}, 0},
      {"--serve, clients", {"--serve", "0", "--serve-wait", "0", "--no-live-discovery"}, clients},
      {"--serve, clients, online discovery", {"--serve", "0", "--serve-wait", "0"}, clients},
  };
  std::printf("live_bench: %s, %s, %d page clients, median of %d runs\n", folder.c_str(),
              sensor ? ("virtual sensor at 30 Hz, all " + std::to_string(delivered) + " frames")
                           .c_str()
                     : (std::to_string(frames) + " frames, as fast as fusion goes").c_str(),
              clients, repeat);
  std::printf("%-36s %10s %8s %10s %10s %10s\n", "case", "frames/s", "ratio", "fused",
              sensor ? "dropped" : "", "requests");
  double baseline = 0.0;
  for (const Case& c : cases) {
    std::vector<double> rates;
    Run last;
    for (int r = 0; r < repeat; ++r) {
      std::vector<std::string> args = base;
      args.insert(args.end(), c.extra.begin(), c.extra.end());
      last = runObjscan(args, c.clients);
      rates.push_back(last.frames_per_s);
      fs::remove_all(out);
    }
    const double rate = median(rates);
    if (baseline == 0.0) baseline = rate;
    const std::string dropped =
        sensor ? std::to_string(delivered > last.read ? delivered - last.read : 0) : "";
    std::printf("%-36s %10.1f %8.3f %10zu %10s %10zu\n", c.name, rate, rate / baseline, last.read,
                dropped.c_str(), last.requests);
    std::fflush(stdout);
  }
  mg_exit_library();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return objscan::bench::guardedMain("live_bench", run, argc, argv);
}
