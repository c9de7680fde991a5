// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/tetgen_worker.h"

#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

extern char** environ;

namespace spidarcad::app {
namespace {

// The request starts with these (version 1 of the format below).
constexpr std::uint32_t kMagic = 0x57545053;  // "SPTW"
constexpr std::uint32_t kVersion = 1;
// Largest vertex / triangle / node / tet count either side accepts (indices are int32).
constexpr std::uint64_t kMaxCount = std::numeric_limits<std::int32_t>::max() / 4;
// Longest string field (switches, error messages).
constexpr std::uint64_t kMaxString = 1 << 20;
// The parent polls its cancel flag this often while waiting for the child (ms).
constexpr int kPollMs = 5;

// Answer record tags.
constexpr char kProgress = 'P';
constexpr char kResult = 'R';
constexpr char kError = 'E';
// Error kinds (kError records).
enum ErrorKind : std::uint8_t {
  kSurfaceDefect = 1,
  kTetgen = 2,
  kInvalidArgument = 3,
  kRuntime = 4,
  kCancelled = 5,
};

std::mutex g_program_mutex;
std::string g_program;

// ---- encoding (host byte order: parent and child are the same executable) ----

class Writer {
 public:
  template <typename T>
  void Put(const T& v) {
    const auto* p = reinterpret_cast<const char*>(&v);
    bytes_.insert(bytes_.end(), p, p + sizeof(T));
  }
  void PutRaw(const void* data, std::size_t n) {
    const auto* p = static_cast<const char*>(data);
    bytes_.insert(bytes_.end(), p, p + n);
  }
  void PutString(const std::string& s) {
    Put<std::uint64_t>(s.size());
    PutRaw(s.data(), s.size());
  }
  const std::vector<char>& bytes() const { return bytes_; }

 private:
  std::vector<char> bytes_;
};

// Thrown by Reader when the stream ends inside a record.
struct StreamEnded {};

// Reads exactly n bytes or throws (StreamEnded, std::runtime_error for bad counts); `source` fills
// a buffer (returns bytes read, 0 at EOF).
class Reader {
 public:
  using Source = std::function<std::size_t(char*, std::size_t)>;
  explicit Reader(Source source) : source_(std::move(source)) {}
  void GetRaw(void* data, std::size_t n) {
    auto* p = static_cast<char*>(data);
    while (n > 0) {
      const std::size_t got = source_(p, n);
      if (got == 0) throw StreamEnded{};
      p += got;
      n -= got;
    }
  }
  template <typename T>
  T Get() {
    T v;
    GetRaw(&v, sizeof(T));
    return v;
  }
  std::uint64_t GetCount(const char* what) {
    const auto n = Get<std::uint64_t>();
    if (n > kMaxCount) throw std::runtime_error(std::string("bad ") + what + " count");
    return n;
  }
  std::string GetString() {
    const auto n = Get<std::uint64_t>();
    if (n > kMaxString) throw std::runtime_error("bad string length");
    std::string s(n, '\0');
    GetRaw(s.data(), n);
    return s;
  }

 private:
  Source source_;
};

void PutMesh(Writer& w, const modeling::TetMesh& m) {
  w.Put<std::uint64_t>(static_cast<std::uint64_t>(m.nodes.cols()));
  w.PutRaw(m.nodes.data(), sizeof(double) * m.nodes.size());
  w.Put<std::uint64_t>(static_cast<std::uint64_t>(m.tets.cols()));
  w.PutRaw(m.tets.data(), sizeof(int) * m.tets.size());
  w.Put<std::uint64_t>(static_cast<std::uint64_t>(m.regions.size()));
  w.PutRaw(m.regions.data(), sizeof(int) * m.regions.size());
}

modeling::TetMesh GetMesh(Reader& r) {
  modeling::TetMesh m;
  const auto nodes = r.GetCount("node");
  m.nodes.resize(3, static_cast<Eigen::Index>(nodes));
  r.GetRaw(m.nodes.data(), sizeof(double) * m.nodes.size());
  const auto tets = r.GetCount("tet");
  m.tets.resize(4, static_cast<Eigen::Index>(tets));
  r.GetRaw(m.tets.data(), sizeof(int) * m.tets.size());
  const auto regions = r.GetCount("region");
  m.regions.resize(static_cast<Eigen::Index>(regions));
  r.GetRaw(m.regions.data(), sizeof(int) * m.regions.size());
  return m;
}

void PutStats(Writer& w, const modeling::TetMeshStats& s) {
  w.Put(s.check_seconds);
  w.Put(s.tetgen_seconds);
  w.PutString(s.switches);
  w.Put<std::int64_t>(s.welded_vertices);
  w.Put<std::int64_t>(s.dropped_triangles);
  w.Put(s.quality.min_dihedral_deg);
  w.Put(s.quality.max_dihedral_deg);
  w.Put(s.quality.max_radius_edge);
  w.Put(s.quality.min_volume);
  w.Put(s.quality.total_volume);
}

modeling::TetMeshStats GetStats(Reader& r) {
  modeling::TetMeshStats s;
  s.check_seconds = r.Get<double>();
  s.tetgen_seconds = r.Get<double>();
  s.switches = r.GetString();
  s.welded_vertices = static_cast<long>(r.Get<std::int64_t>());
  s.dropped_triangles = static_cast<long>(r.Get<std::int64_t>());
  s.quality.min_dihedral_deg = r.Get<double>();
  s.quality.max_dihedral_deg = r.Get<double>();
  s.quality.max_radius_edge = r.Get<double>();
  s.quality.min_volume = r.Get<double>();
  s.quality.total_volume = r.Get<double>();
  return s;
}

std::vector<char> EncodeRequest(const modeling::TriangleMesh& surface,
                                const modeling::TetMeshSettings& s) {
  Writer w;
  w.Put(kMagic);
  w.Put(kVersion);
  w.Put(s.max_radius_edge);
  w.Put(s.min_dihedral_deg);
  w.Put(s.max_volume);
  w.Put(s.weld_tolerance);
  w.Put<std::uint8_t>(s.preserve_surface);
  w.Put<std::uint8_t>(s.keep_facets);
  w.Put<std::uint8_t>(s.quiet);
  w.Put<std::uint8_t>(s.check_surface);
  w.Put<std::uint8_t>(static_cast<bool>(s.progress));
  w.PutString(s.extra_switches);
  w.Put<std::uint64_t>(static_cast<std::uint64_t>(surface.vertices.cols()));
  w.PutRaw(surface.vertices.data(), sizeof(double) * surface.vertices.size());
  w.Put<std::uint64_t>(static_cast<std::uint64_t>(surface.triangles.cols()));
  w.PutRaw(surface.triangles.data(), sizeof(int) * surface.triangles.size());
  return w.bytes();
}

std::string SignalText(int sig) {
  const char* name = sigabbrev_np(sig);
  return "signal " + std::to_string(sig) +
         (name != nullptr ? std::string(" (SIG") + name + ")" : "");
}

// The parent's end of one worker run: kills and reaps the child on every way out.
class Child {
 public:
  Child(const std::string& program, const std::atomic<bool>* cancel) : cancel_(cancel) {
    int fds[2];
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0)
      throw std::runtime_error(std::string("TetGen worker: socketpair: ") + std::strerror(errno));
    fd_ = fds[0];
    posix_spawn_file_actions_t actions;
    posix_spawnattr_t attr;
    posix_spawn_file_actions_init(&actions);
    posix_spawnattr_init(&attr);
    // Its socket on stdin; TetGen's console output (settings.quiet false) to our stderr.
    posix_spawn_file_actions_adddup2(&actions, fds[1], 0);
    posix_spawn_file_actions_adddup2(&actions, 2, 1);
    // Default signal dispositions and no blocked signals, whatever this thread has; its own
    // process group, so that a Ctrl+C at a terminal reaches only this process (the child dies
    // with its parent: the worker sets PR_SET_PDEATHSIG).
    sigset_t none, all;
    sigemptyset(&none);
    sigfillset(&all);
    posix_spawnattr_setsigmask(&attr, &none);
    posix_spawnattr_setsigdefault(&attr, &all);
    posix_spawnattr_setpgroup(&attr, 0);
    posix_spawnattr_setflags(
        &attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETPGROUP);
    const std::string parent = std::to_string(getpid());
    std::vector<char*> argv = {
        const_cast<char*>(program.c_str()), const_cast<char*>(kTetgenWorkerCommand),
        const_cast<char*>("--parent"), const_cast<char*>(parent.c_str()), nullptr};
    const int rc = posix_spawn(&pid_, program.c_str(), &actions, &attr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attr);
    close(fds[1]);
    if (rc != 0) {
      close(fd_);
      fd_ = -1;
      pid_ = -1;
      throw std::runtime_error("TetGen worker: cannot start '" + program +
                               "': " + std::strerror(rc));
    }
  }
  ~Child() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      Reap();
    }
    if (fd_ >= 0) close(fd_);
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  bool cancelled() const { return cancel_ != nullptr && cancel_->load(std::memory_order_relaxed); }

  // Sends all bytes, polling the cancel flag (throws TetMeshingCancelled).
  void Send(const std::vector<char>& bytes) {
    std::size_t done = 0;
    while (done < bytes.size()) {
      Wait(POLLOUT);
      const ssize_t n = send(fd_, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
      if (n < 0) {
        if (errno == EINTR || errno == EAGAIN) continue;
        throw Died();  // the child went away (EPIPE): say how
      }
      done += static_cast<std::size_t>(n);
    }
  }

  // Receives up to n bytes (0 at end of stream), polling the cancel flag.
  std::size_t Receive(char* data, std::size_t n) {
    for (;;) {
      Wait(POLLIN);
      const ssize_t got = recv(fd_, data, n, 0);
      if (got < 0) {
        if (errno == EINTR || errno == EAGAIN) continue;
        throw std::runtime_error(std::string("TetGen worker: recv: ") + std::strerror(errno));
      }
      return static_cast<std::size_t>(got);
    }
  }

  // The error for a child that ended without an answer (reaps it).
  modeling::TetgenError Died() {
    if (cancelled()) throw modeling::TetMeshingCancelled();
    const int status = Reap();
    if (WIFSIGNALED(status))
      return modeling::TetgenError(
          0, "TetGen worker process was killed by " + SignalText(WTERMSIG(status)));
    if (WIFEXITED(status))
      return modeling::TetgenError(0, "TetGen worker process exited with status " +
                                          std::to_string(WEXITSTATUS(status)) +
                                          " without an answer");
    return modeling::TetgenError(0, "TetGen worker process ended without an answer");
  }

  // Waits for the child's exit after its answer (it exits at once).
  void Finish() { Reap(); }

 private:
  // Waits until the socket is ready for `events`; throws TetMeshingCancelled when the flag
  // is raised (the destructor kills the child).
  void Wait(short events) {
    for (;;) {
      if (cancelled()) throw modeling::TetMeshingCancelled();
      pollfd p{fd_, events, 0};
      const int rc = poll(&p, 1, kPollMs);
      if (rc > 0) return;  // ready, or hung up / error: the send or recv says which
      if (rc < 0 && errno != EINTR)
        throw std::runtime_error(std::string("TetGen worker: poll: ") + std::strerror(errno));
    }
  }

  int Reap() {
    int status = 0;
    if (pid_ <= 0) return status_;
    while (waitpid(pid_, &status, 0) < 0) {
      if (errno != EINTR) {
        status = 0;
        break;
      }
    }
    pid_ = -1;
    status_ = status;
    return status;
  }

  const std::atomic<bool>* cancel_;
  int fd_ = -1;
  pid_t pid_ = -1;
  int status_ = 0;
};

[[noreturn]] void Rethrow(std::uint8_t kind, std::int32_t code, const std::string& message) {
  switch (kind) {
    case kSurfaceDefect:
      throw modeling::SurfaceDefectError(message);
    case kTetgen:
      throw modeling::TetgenError(code, message);
    case kInvalidArgument:
      throw std::invalid_argument(message);
    case kCancelled:
      throw modeling::TetMeshingCancelled();
    default:
      throw std::runtime_error(message);
  }
}

modeling::TetMesh RunInChild(const std::string& program, const modeling::TriangleMesh& surface,
                             const modeling::TetMeshSettings& settings,
                             modeling::TetMeshStats* stats) {
  if (settings.cancel->load()) throw modeling::TetMeshingCancelled();
  if (surface.vertices.cols() > static_cast<Eigen::Index>(kMaxCount) ||
      surface.triangles.cols() > static_cast<Eigen::Index>(kMaxCount))
    throw std::invalid_argument("TetGen: the surface has too many vertices or triangles");
  const std::vector<char> request = EncodeRequest(surface, settings);
  Child child(program, settings.cancel);
  child.Send(request);
  Reader reader([&child](char* p, std::size_t n) { return child.Receive(p, n); });
  for (;;) {
    char tag = 0;
    try {
      tag = reader.Get<char>();
      if (tag == kProgress) {
        const double f = reader.Get<double>();
        if (settings.progress) settings.progress(f);
        continue;
      }
      if (tag == kError) {
        const auto kind = reader.Get<std::uint8_t>();
        const auto code = reader.Get<std::int32_t>();
        const std::string message = reader.GetString();
        child.Finish();
        Rethrow(kind, code, message);
      }
      if (tag == kResult) {
        modeling::TetMeshStats st = GetStats(reader);
        modeling::TetMesh mesh = GetMesh(reader);
        child.Finish();
        ValidateTetMesh(mesh);
        if (stats != nullptr) *stats = std::move(st);
        return mesh;
      }
    } catch (const StreamEnded&) {
      // No answer, or a cut-off one: the child died (Died throws TetMeshingCancelled when the
      // flag was raised meanwhile).
      throw child.Died();
    }
    throw modeling::TetgenError(0, "TetGen worker process sent a malformed answer (record tag " +
                                       std::to_string(static_cast<int>(tag)) + ")");
  }
}

// Blocking I/O on the child's side.
std::size_t ReadSome(int fd, char* p, std::size_t n) {
  for (;;) {
    const ssize_t got = read(fd, p, n);
    if (got >= 0) return static_cast<std::size_t>(got);
    if (errno != EINTR) return 0;
  }
}

bool WriteAll(int fd, const std::vector<char>& bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  return true;
}

}  // namespace

void SetTetgenWorkerProgram(const std::string& path) {
  std::lock_guard<std::mutex> lock(g_program_mutex);
  g_program = path;
}

std::string TetgenWorkerProgram() {
  std::lock_guard<std::mutex> lock(g_program_mutex);
  return g_program;
}

modeling::TetMesh TetrahedralizeCancellable(const modeling::TriangleMesh& surface,
                                            const modeling::TetMeshSettings& settings,
                                            modeling::TetMeshStats* stats) {
  const std::string program = TetgenWorkerProgram();
  if (settings.cancel == nullptr || program.empty())
    return modeling::TetrahedralizeSurface(surface, settings, stats);
  return RunInChild(program, surface, settings, stats);
}

int RunTetgenWorker(int in, int out) {
  modeling::TriangleMesh surface;
  modeling::TetMeshSettings settings;
  bool progress = false;
  try {
    Reader r([in](char* p, std::size_t n) { return ReadSome(in, p, n); });
    if (r.Get<std::uint32_t>() != kMagic || r.Get<std::uint32_t>() != kVersion)
      throw std::runtime_error("not a TetGen worker request of version 1");
    settings.max_radius_edge = r.Get<double>();
    settings.min_dihedral_deg = r.Get<double>();
    settings.max_volume = r.Get<double>();
    settings.weld_tolerance = r.Get<double>();
    settings.preserve_surface = r.Get<std::uint8_t>() != 0;
    settings.keep_facets = r.Get<std::uint8_t>() != 0;
    settings.quiet = r.Get<std::uint8_t>() != 0;
    settings.check_surface = r.Get<std::uint8_t>() != 0;
    progress = r.Get<std::uint8_t>() != 0;
    settings.extra_switches = r.GetString();
    const auto nv = r.GetCount("vertex");
    surface.vertices.resize(3, static_cast<Eigen::Index>(nv));
    r.GetRaw(surface.vertices.data(), sizeof(double) * surface.vertices.size());
    const auto nt = r.GetCount("triangle");
    surface.triangles.resize(3, static_cast<Eigen::Index>(nt));
    r.GetRaw(surface.triangles.data(), sizeof(int) * surface.triangles.size());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "spidarcad %s: bad request: %s\n", kTetgenWorkerCommand, e.what());
    return 2;
  } catch (const StreamEnded&) {
    std::fprintf(stderr, "spidarcad %s: bad request: it ends early\n", kTetgenWorkerCommand);
    return 2;
  }
  if (progress) {
    settings.progress = [out](double f) {
      Writer w;
      w.Put(kProgress);
      w.Put(f);
      WriteAll(out, w.bytes());
    };
  }
  Writer answer;
  const auto error = [&answer](ErrorKind kind, int code, const char* what) {
    answer.Put(kError);
    answer.Put<std::uint8_t>(kind);
    answer.Put<std::int32_t>(code);
    std::string message(what);
    if (message.size() > kMaxString) message.resize(kMaxString);
    answer.PutString(message);
  };
  try {
    modeling::TetMeshStats stats;
    const modeling::TetMesh mesh = modeling::TetrahedralizeSurface(surface, settings, &stats);
    answer.Put(kResult);
    PutStats(answer, stats);
    PutMesh(answer, mesh);
  } catch (const modeling::SurfaceDefectError& e) {
    error(kSurfaceDefect, 0, e.what());
  } catch (const modeling::TetgenError& e) {
    error(kTetgen, e.code(), e.what());
  } catch (const modeling::TetMeshingCancelled& e) {
    error(kCancelled, 0, e.what());
  } catch (const std::invalid_argument& e) {
    error(kInvalidArgument, 0, e.what());
  } catch (const std::bad_alloc&) {
    error(kTetgen, 1, "TetGen failed: out of memory");
  } catch (const std::exception& e) {
    error(kRuntime, 0, e.what());
  }
  return WriteAll(out, answer.bytes()) ? 0 : 1;
}

}  // namespace spidarcad::app
