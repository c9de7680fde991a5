// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/worker_process.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include "spidarcad/modeling/scene_io.h"

extern char** environ;

namespace spidarcad::app {
namespace {

// The request starts with these (version 1 of the format below).
constexpr std::uint32_t kMagic = 0x57545053;  // "SPTW"
constexpr std::uint32_t kVersion = 1;
// What the request asks for (after the version).
enum RequestKind : std::uint8_t { kTetgenRequest = 1, kCgalRequest = 2, kFactorRequest = 3 };
// Largest vertex / triangle / node / tet count either side accepts (indices are int32).
constexpr std::uint64_t kMaxCount = std::numeric_limits<std::int32_t>::max() / 4;
// Longest string field (switches, error messages; a scene's node tree as JSON: the scene file
// limit, 64 MiB, with room for the re-encoding).
constexpr std::uint64_t kMaxString = std::uint64_t{256} << 20;
// The parent polls its cancel flag this often while waiting for the child (ms).
constexpr int kPollMs = 5;
// The parent copies K_ff into the shared memory in chunks of this many bytes, polling its
// cancel flag between them.
constexpr std::size_t kCopyChunk = std::size_t{16} << 20;

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
  kCgal = 6,
  kCgalCancelled = 7,
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

// The quality figures of a tetrahedral mesh (TetGen's and CGAL's stats share them).
void PutQuality(Writer& w, const modeling::TetQuality& q) {
  for (double v :
       {q.min_dihedral_deg, q.max_dihedral_deg, q.max_radius_edge, q.min_volume, q.total_volume})
    w.Put(v);
}

modeling::TetQuality GetQuality(Reader& r) {
  modeling::TetQuality q;
  for (double* v : {&q.min_dihedral_deg, &q.max_dihedral_deg, &q.max_radius_edge, &q.min_volume,
                    &q.total_volume})
    *v = r.Get<double>();
  return q;
}

void PutStats(Writer& w, const modeling::TetMeshStats& s) {
  w.Put(s.check_seconds);
  w.Put(s.tetgen_seconds);
  w.PutString(s.switches);
  w.Put<std::int64_t>(s.welded_vertices);
  w.Put<std::int64_t>(s.dropped_triangles);
  PutQuality(w, s.quality);
}

modeling::TetMeshStats GetStats(Reader& r) {
  modeling::TetMeshStats s;
  s.check_seconds = r.Get<double>();
  s.tetgen_seconds = r.Get<double>();
  s.switches = r.GetString();
  s.welded_vertices = static_cast<long>(r.Get<std::int64_t>());
  s.dropped_triangles = static_cast<long>(r.Get<std::int64_t>());
  s.quality = GetQuality(r);
  return s;
}

std::vector<char> EncodeRequest(const modeling::TriangleMesh& surface,
                                const modeling::TetMeshSettings& s) {
  Writer w;
  w.Put(kMagic);
  w.Put(kVersion);
  w.Put<std::uint8_t>(kTetgenRequest);
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

// Thrown by Child: the cancel flag was raised (the caller throws its mesher's cancellation).
struct ChildCancelled {};
// Thrown by Child: the child ended without an answer; `message` says how, naming `what`.
struct ChildDied {
  std::string message;
};

std::vector<char> EncodeCgalRequest(const modeling::ImplicitNode& root,
                                    const Eigen::AlignedBox3d& bounds,
                                    const modeling::CgalMeshSettings& s) {
  Writer w;
  w.Put(kMagic);
  w.Put(kVersion);
  w.Put<std::uint8_t>(kCgalRequest);
  w.PutString(modeling::NodeToJson(root).dump());
  w.PutRaw(bounds.min().data(), 3 * sizeof(double));
  w.PutRaw(bounds.max().data(), 3 * sizeof(double));
  w.Put(s.facet_angle_deg);
  w.Put(s.facet_size);
  w.Put(s.facet_distance);
  w.Put(s.cell_radius_edge_ratio);
  w.Put(s.cell_size);
  w.Put<std::uint8_t>(s.lloyd);
  w.Put<std::uint8_t>(s.odt);
  w.Put<std::uint8_t>(s.perturb);
  w.Put<std::uint8_t>(s.exude);
  w.Put(s.sliver_bound_deg);
  w.Put(s.optimizer_time_limit);
  w.Put(s.exude_time_limit);
  w.Put<std::int32_t>(s.smoothing_iterations);
  w.Put<std::int64_t>(s.max_vertices);
  w.Put<std::uint32_t>(s.seed);
  w.Put(s.relative_error_bound);
  w.Put<std::uint8_t>(static_cast<bool>(s.progress));
  return w.bytes();
}

void PutCgalStats(Writer& w, const modeling::CgalMeshStats& s) {
  for (double v : {s.seconds, s.seed_seconds, s.refine_seconds, s.optimize_seconds}) w.Put(v);
  for (long v : {s.seed_points, s.refine_steps, s.vertices, s.tets, s.boundary_facets})
    w.Put<std::int64_t>(v);
  w.Put(s.min_dihedral_deg);
  PutQuality(w, s.quality);
}

modeling::CgalMeshStats GetCgalStats(Reader& r) {
  modeling::CgalMeshStats s;
  for (double* v : {&s.seconds, &s.seed_seconds, &s.refine_seconds, &s.optimize_seconds})
    *v = r.Get<double>();
  for (long* v : {&s.seed_points, &s.refine_steps, &s.vertices, &s.tets, &s.boundary_facets})
    *v = static_cast<long>(r.Get<std::int64_t>());
  s.min_dihedral_deg = r.Get<double>();
  s.quality = GetQuality(r);
  return s;
}

std::string SignalText(int sig) {
  const char* name = sigabbrev_np(sig);
  return "signal " + std::to_string(sig) +
         (name != nullptr ? std::string(" (SIG") + name + ")" : "");
}

// The parent's end of one worker run: kills and reaps the child on every way out.
class Child {
 public:
  // `what` names the library in errors ("TetGen", "CGAL", "CHOLMOD"); `shared`, when not −1,
  // is given to the child as its fd kSharedFd.
  Child(const std::string& program, const std::atomic<bool>* cancel, const char* what,
        int shared = -1)
      : cancel_(cancel), what_(what) {
    int fds[2];
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0)
      throw std::runtime_error(what_ + " worker: socketpair: " + std::strerror(errno));
    fd_ = fds[0];
    posix_spawn_file_actions_t actions;
    posix_spawnattr_t attr;
    posix_spawn_file_actions_init(&actions);
    posix_spawnattr_init(&attr);
    // Its socket on stdin; TetGen's console output (settings.quiet false) to our stderr.
    posix_spawn_file_actions_adddup2(&actions, fds[1], 0);
    posix_spawn_file_actions_adddup2(&actions, 2, 1);
    if (shared >= 0) posix_spawn_file_actions_adddup2(&actions, shared, kSharedFd);
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
    std::vector<char*> argv = {const_cast<char*>(program.c_str()),
                               const_cast<char*>(kWorkerCommand), const_cast<char*>("--parent"),
                               const_cast<char*>(parent.c_str()), nullptr};
    const int rc = posix_spawn(&pid_, program.c_str(), &actions, &attr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attr);
    close(fds[1]);
    if (rc != 0) {
      close(fd_);
      fd_ = -1;
      pid_ = -1;
      throw std::runtime_error(what_ + " worker: cannot start '" + program +
                               "': " + std::strerror(rc));
    }
  }
  ~Child() {
    if (pid_ > 0) {
      // Killed (cancelled, or a failure on this side). A child that dies with hundreds of MB
      // takes a while to free them: a thread of its own reaps it, so that the caller (a
      // cancelled job) does not wait for that.
      kill(pid_, SIGKILL);
      const pid_t pid = pid_;
      try {
        std::thread([pid] {
          int status = 0;
          while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
          }
        }).detach();
        pid_ = -1;
      } catch (const std::system_error&) {
        Reap();
      }
    }
    if (fd_ >= 0) close(fd_);
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  bool cancelled() const { return cancel_ != nullptr && cancel_->load(std::memory_order_relaxed); }

  // Sends all bytes, polling the cancel flag (throws ChildCancelled, ChildDied).
  void Send(const std::vector<char>& bytes) {
    std::size_t done = 0;
    while (done < bytes.size()) {
      Wait(POLLOUT);
      const ssize_t n = send(fd_, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
      if (n < 0) {
        if (errno == EINTR || errno == EAGAIN) continue;
        Died();  // the child went away (EPIPE): say how
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
        // Reset: the child went away before reading all of the request.
        if (errno == ECONNRESET) Died();
        throw std::runtime_error(what_ + " worker: recv: " + std::strerror(errno));
      }
      return static_cast<std::size_t>(got);
    }
  }

  // For a child that ended without an answer: reaps it and throws ChildDied saying how (or
  // ChildCancelled when the flag was raised meanwhile).
  [[noreturn]] void Died() {
    if (cancelled()) throw ChildCancelled{};
    const int status = Reap();
    if (WIFSIGNALED(status))
      throw ChildDied{what_ + " worker process was killed by " + SignalText(WTERMSIG(status))};
    if (WIFEXITED(status))
      throw ChildDied{what_ + " worker process exited with status " +
                      std::to_string(WEXITSTATUS(status)) + " without an answer"};
    throw ChildDied{what_ + " worker process ended without an answer"};
  }

  // Waits for the child's exit after its answer (it exits at once).
  void Finish() { Reap(); }

 private:
  // Waits until the socket is ready for `events`; throws ChildCancelled when the flag is
  // raised (the destructor kills the child).
  void Wait(short events) {
    for (;;) {
      if (cancelled()) throw ChildCancelled{};
      pollfd p{fd_, events, 0};
      const int rc = poll(&p, 1, kPollMs);
      if (rc > 0) return;  // ready, or hung up / error: the send or recv says which
      if (rc < 0 && errno != EINTR)
        throw std::runtime_error(what_ + " worker: poll: " + std::strerror(errno));
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
  std::string what_;
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
    case kCgal:
      throw modeling::CgalMeshError(message);
    case kCgalCancelled:
      throw modeling::CgalMeshCancelled();
    default:
      throw std::runtime_error(message);
  }
}

// Sends `request` to a new child and reads its answer: progress records go to `progress`, an
// error record is rethrown as its type, a result record is read by `read_result`. Throws
// ChildCancelled and ChildDied (the callers turn them into their mesher's exceptions).
void RunInChild(const std::string& program, const std::atomic<bool>* cancel, const char* what,
                const std::vector<char>& request, const std::function<void(double)>& progress,
                const std::function<void(Reader&)>& read_result, int shared = -1) {
  Child child(program, cancel, what, shared);
  child.Send(request);
  Reader reader([&child](char* p, std::size_t n) { return child.Receive(p, n); });
  for (;;) {
    char tag = 0;
    try {
      tag = reader.Get<char>();
      if (tag == kProgress) {
        const double f = reader.Get<double>();
        if (progress) progress(f);
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
        read_result(reader);
        child.Finish();
        return;
      }
    } catch (const StreamEnded&) {
      // No answer, or a cut-off one: the child died.
      child.Died();
    }
    throw ChildDied{std::string(what) + " worker process sent a malformed answer (record tag " +
                    std::to_string(static_cast<int>(tag)) + ")"};
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

// A file descriptor closed with its scope.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

// A shared mapping of `bytes` bytes of fd, unmapped with its scope.
class Mapping {
 public:
  Mapping(int fd, std::size_t bytes, bool writable) : bytes_(bytes) {
    if (bytes_ == 0) return;
    void* p =
        mmap(nullptr, bytes_, writable ? PROT_READ | PROT_WRITE : PROT_READ, MAP_SHARED, fd, 0);
    if (p == MAP_FAILED) throw std::runtime_error(std::string("mmap: ") + std::strerror(errno));
    data_ = static_cast<char*>(p);
  }
  ~Mapping() {
    if (data_ != nullptr) munmap(data_, bytes_);
  }
  Mapping(const Mapping&) = delete;
  Mapping& operator=(const Mapping&) = delete;
  char* data() const { return data_; }

 private:
  char* data_ = nullptr;
  std::size_t bytes_;
};

// Size of the file behind fd, bytes.
std::size_t FileBytes(int fd) {
  struct stat st = {};
  if (fstat(fd, &st) != 0) throw std::runtime_error(std::string("fstat: ") + std::strerror(errno));
  return static_cast<std::size_t>(st.st_size);
}

// Sets the size of the file behind fd (a memfd: memory, not disk); std::bad_alloc when the
// memory is not there.
void Resize(int fd, std::size_t bytes) {
  while (ftruncate(fd, static_cast<off_t>(bytes)) != 0) {
    if (errno == EINTR) continue;
    if (errno == ENOMEM || errno == ENOSPC || errno == EFBIG) throw std::bad_alloc();
    throw std::runtime_error(std::string("ftruncate: ") + std::strerror(errno));
  }
}

// The factor request's arrays in the shared memory: K_ff's column pointers (n + 1 int32), row
// indices and values (nnz int32 and doubles), each starting on an 8-byte boundary.
struct MatrixLayout {
  std::size_t outer = 0, inner = 0, values = 0, end = 0;
  MatrixLayout(std::uint64_t n, std::uint64_t nnz) {
    const auto padded = [](std::uint64_t b) { return (b + 7) & ~std::uint64_t{7}; };
    inner = padded(4 * (n + 1));
    values = inner + padded(4 * nnz);
    end = values + 8 * nnz;
  }
};

// Copies n bytes in chunks, polling the cancel flag between them; false when it was raised.
bool CopyPolling(char* to, const void* from, std::size_t n, const std::atomic<bool>* cancel) {
  const auto* src = static_cast<const char*>(from);
  for (std::size_t done = 0; done < n;) {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) return false;
    const std::size_t chunk = std::min(kCopyChunk, n - done);
    std::memcpy(to + done, src + done, chunk);
    done += chunk;
  }
  return true;
}

// The child's side of a factor request: K_ff from the shared memory, checked (CHOLMOD reads it
// unchecked), factorised, its flat form written back over it. Returns the flat form's bytes.
std::uint64_t FactorizeShared(int shared, std::uint64_t n, std::uint64_t nnz) {
  const MatrixLayout layout(n, nnz);
  if (FileBytes(shared) < layout.end)
    throw std::runtime_error("the shared memory is smaller than the request says");
  fem::SparseMatrixd a(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  {
    const Mapping request(shared, layout.end, false);
    a.resizeNonZeros(static_cast<Eigen::Index>(nnz));
    std::memcpy(a.outerIndexPtr(), request.data(), 4 * (n + 1));
    std::memcpy(a.innerIndexPtr(), request.data() + layout.inner, 4 * nnz);
    std::memcpy(a.valuePtr(), request.data() + layout.values, 8 * nnz);
  }
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  if (outer[0] != 0 || static_cast<std::uint64_t>(outer[n]) != nnz)
    throw std::runtime_error("bad column pointers");
  for (std::uint64_t c = 0; c < n; ++c) {
    if (outer[c + 1] < outer[c]) throw std::runtime_error("bad column pointers");
    for (int k = outer[c]; k < outer[c + 1]; ++k)
      if (inner[k] < 0 || static_cast<std::uint64_t>(inner[k]) >= n ||
          (k > outer[c] && inner[k] <= inner[k - 1]))
        throw std::runtime_error("bad row indices");
  }
  fem::CholeskyFactor factor;
  factor.Compute(a);
  a = fem::SparseMatrixd();
  const std::size_t flat = factor.FlatBytes();
  Resize(shared, flat);
  const Mapping answer(shared, flat, true);
  factor.WriteFlat(answer.data());
  return flat;
}

}  // namespace

void SetWorkerProgram(const std::string& path) {
  std::lock_guard<std::mutex> lock(g_program_mutex);
  g_program = path;
}

std::string WorkerProgram() {
  std::lock_guard<std::mutex> lock(g_program_mutex);
  return g_program;
}

modeling::TetMesh TetrahedralizeCancellable(const modeling::TriangleMesh& surface,
                                            const modeling::TetMeshSettings& settings,
                                            modeling::TetMeshStats* stats) {
  const std::string program = WorkerProgram();
  if (settings.cancel == nullptr || program.empty())
    return modeling::TetrahedralizeSurface(surface, settings, stats);
  if (settings.cancel->load()) throw modeling::TetMeshingCancelled();
  if (surface.vertices.cols() > static_cast<Eigen::Index>(kMaxCount) ||
      surface.triangles.cols() > static_cast<Eigen::Index>(kMaxCount))
    throw std::invalid_argument("TetGen: the surface has too many vertices or triangles");
  modeling::TetMesh mesh;
  modeling::TetMeshStats st;
  try {
    RunInChild(program, settings.cancel, "TetGen", EncodeRequest(surface, settings),
               settings.progress, [&](Reader& r) {
                 st = GetStats(r);
                 mesh = GetMesh(r);
               });
  } catch (const ChildCancelled&) {
    throw modeling::TetMeshingCancelled();
  } catch (const ChildDied& e) {
    throw modeling::TetgenError(0, e.message);
  }
  modeling::ValidateTetMesh(mesh);
  if (stats != nullptr) *stats = std::move(st);
  return mesh;
}

modeling::TetMesh MeshWithCgalCancellable(const modeling::ImplicitNode& root,
                                          const modeling::CompiledSolid& compiled,
                                          const Eigen::AlignedBox3d& bounds,
                                          const modeling::CgalMeshSettings& settings,
                                          modeling::CgalMeshStats* stats) {
  const std::string program = WorkerProgram();
  if (settings.cancel == nullptr || program.empty())
    return modeling::MeshImplicitWithCgal(compiled, bounds, settings, stats);
  if (settings.cancel->load()) throw modeling::CgalMeshCancelled();
  modeling::TetMesh mesh;
  modeling::CgalMeshStats st;
  try {
    RunInChild(program, settings.cancel, "CGAL", EncodeCgalRequest(root, bounds, settings),
               settings.progress, [&](Reader& r) {
                 st = GetCgalStats(r);
                 mesh = GetMesh(r);
               });
  } catch (const ChildCancelled&) {
    throw modeling::CgalMeshCancelled();
  } catch (const ChildDied& e) {
    throw modeling::CgalMeshError(e.message);
  }
  modeling::ValidateTetMesh(mesh);
  if (stats != nullptr) *stats = st;
  return mesh;
}

std::unique_ptr<fem::CholeskyFactor> FactorizeCancellable(const fem::SparseMatrixd& k_ff,
                                                          const std::atomic<bool>* cancel) {
  const std::string program = WorkerProgram();
  if (cancel == nullptr || program.empty()) {
    auto factor = std::make_unique<fem::CholeskyFactor>();
    factor->Compute(k_ff);
    return factor;
  }
  if (cancel->load()) throw FactorizationCancelled();
  if (k_ff.rows() != k_ff.cols() || k_ff.rows() < 1 || !k_ff.isCompressed())
    throw std::invalid_argument("CHOLMOD worker: K_ff must be square, not empty, and compressed");
  const auto n = static_cast<std::uint64_t>(k_ff.rows());
  const auto nnz = static_cast<std::uint64_t>(k_ff.nonZeros());
  // K_ff into a memory file (memfd: no disk) that the child gets as its fd kSharedFd and
  // overwrites with the factor's flat form. Kept off fd kSharedFd here, so that the spawn's
  // dup2 onto it clears close-on-exec.
  const Fd created(memfd_create("spidarcad-factor", MFD_CLOEXEC));
  if (created.get() < 0)
    throw std::runtime_error(std::string("CHOLMOD worker: memfd_create: ") + std::strerror(errno));
  const Fd shared(fcntl(created.get(), F_DUPFD_CLOEXEC, kSharedFd + 1));
  if (shared.get() < 0)
    throw std::runtime_error(std::string("CHOLMOD worker: fcntl: ") + std::strerror(errno));
  const MatrixLayout layout(n, nnz);
  Resize(shared.get(), layout.end);
  {
    const Mapping request(shared.get(), layout.end, true);
    if (!CopyPolling(request.data(), k_ff.outerIndexPtr(), 4 * (n + 1), cancel) ||
        !CopyPolling(request.data() + layout.inner, k_ff.innerIndexPtr(), 4 * nnz, cancel) ||
        !CopyPolling(request.data() + layout.values, k_ff.valuePtr(), 8 * nnz, cancel))
      throw FactorizationCancelled();
  }
  Writer w;
  w.Put(kMagic);
  w.Put(kVersion);
  w.Put<std::uint8_t>(kFactorRequest);
  w.Put<std::uint64_t>(n);
  w.Put<std::uint64_t>(nnz);
  std::unique_ptr<fem::CholeskyFactor> factor;
  try {
    RunInChild(
        program, cancel, "CHOLMOD", w.bytes(), {},
        [&](Reader& r) {
          const auto flat = r.Get<std::uint64_t>();
          if (flat > FileBytes(shared.get()))
            throw ChildDied{"CHOLMOD worker process sent a factor larger than its shared memory"};
          const Mapping answer(shared.get(), flat, false);
          try {
            factor =
                fem::CholeskyFactor::ReadFlat(answer.data(), flat, static_cast<int>(n), cancel);
          } catch (const std::invalid_argument& e) {
            throw ChildDied{std::string("CHOLMOD worker process sent a malformed factor: ") +
                            e.what()};
          }
        },
        shared.get());
  } catch (const ChildCancelled&) {
    throw FactorizationCancelled();
  } catch (const ChildDied& e) {
    throw std::runtime_error(e.message);
  }
  if (factor == nullptr) throw FactorizationCancelled();  // raised during the copy
  return factor;
}

int RunWorker(int in, int out, int shared) {
  std::uint8_t kind = 0;
  modeling::TriangleMesh surface;
  modeling::TetMeshSettings settings;
  modeling::ImplicitNode root;
  Eigen::AlignedBox3d bounds;
  modeling::CgalMeshSettings cgal;
  std::uint64_t factor_n = 0, factor_nnz = 0;
  bool progress = false;
  try {
    Reader r([in](char* p, std::size_t n) { return ReadSome(in, p, n); });
    if (r.Get<std::uint32_t>() != kMagic || r.Get<std::uint32_t>() != kVersion)
      throw std::runtime_error("not a worker request of version 1");
    kind = r.Get<std::uint8_t>();
    if (kind == kTetgenRequest) {
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
    } else if (kind == kCgalRequest) {
      root = modeling::NodeFromJson(nlohmann::json::parse(r.GetString()));
      r.GetRaw(bounds.min().data(), 3 * sizeof(double));
      r.GetRaw(bounds.max().data(), 3 * sizeof(double));
      cgal.facet_angle_deg = r.Get<double>();
      cgal.facet_size = r.Get<double>();
      cgal.facet_distance = r.Get<double>();
      cgal.cell_radius_edge_ratio = r.Get<double>();
      cgal.cell_size = r.Get<double>();
      cgal.lloyd = r.Get<std::uint8_t>() != 0;
      cgal.odt = r.Get<std::uint8_t>() != 0;
      cgal.perturb = r.Get<std::uint8_t>() != 0;
      cgal.exude = r.Get<std::uint8_t>() != 0;
      cgal.sliver_bound_deg = r.Get<double>();
      cgal.optimizer_time_limit = r.Get<double>();
      cgal.exude_time_limit = r.Get<double>();
      cgal.smoothing_iterations = r.Get<std::int32_t>();
      cgal.max_vertices = static_cast<long>(r.Get<std::int64_t>());
      cgal.seed = r.Get<std::uint32_t>();
      cgal.relative_error_bound = r.Get<double>();
      progress = r.Get<std::uint8_t>() != 0;
    } else if (kind == kFactorRequest) {
      factor_n = r.Get<std::uint64_t>();
      factor_nnz = r.Get<std::uint64_t>();
      if (factor_n < 1 || factor_n > kMaxCount ||
          factor_nnz > static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max()) ||
          factor_nnz < factor_n)
        throw std::runtime_error("bad matrix size");
      if (shared < 0) throw std::runtime_error("a factor request needs the shared memory");
    } else {
      throw std::runtime_error("unknown request kind " + std::to_string(kind));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "spidarcad %s: bad request: %s\n", kWorkerCommand, e.what());
    return 2;
  } catch (const StreamEnded&) {
    std::fprintf(stderr, "spidarcad %s: bad request: it ends early\n", kWorkerCommand);
    return 2;
  }
  std::function<void(double)> report;
  if (progress) {
    // CGAL may report from several threads: one record at a time.
    auto mutex = std::make_shared<std::mutex>();
    report = [out, mutex](double f) {
      Writer w;
      w.Put(kProgress);
      w.Put(f);
      std::lock_guard<std::mutex> lock(*mutex);
      WriteAll(out, w.bytes());
    };
  }
  settings.progress = report;
  cgal.progress = report;
  Writer answer;
  const auto error = [&answer](ErrorKind error_kind, int code, const char* what) {
    answer.Put(kError);
    answer.Put<std::uint8_t>(error_kind);
    answer.Put<std::int32_t>(code);
    std::string message(what);
    if (message.size() > kMaxString) message.resize(kMaxString);
    answer.PutString(message);
  };
  try {
    if (kind == kTetgenRequest) {
      modeling::TetMeshStats stats;
      const modeling::TetMesh mesh = modeling::TetrahedralizeSurface(surface, settings, &stats);
      answer.Put(kResult);
      PutStats(answer, stats);
      PutMesh(answer, mesh);
    } else if (kind == kFactorRequest) {
      const std::uint64_t flat = FactorizeShared(shared, factor_n, factor_nnz);
      answer.Put(kResult);
      answer.Put<std::uint64_t>(flat);
    } else {
      // Compiled as FeSolidBounds compiles the window's copy (CompiledSolid::Compile).
      const modeling::CompiledSolid compiled = modeling::CompiledSolid::Compile(root);
      modeling::CgalMeshStats stats;
      const modeling::TetMesh mesh = modeling::MeshImplicitWithCgal(compiled, bounds, cgal, &stats);
      answer.Put(kResult);
      PutCgalStats(answer, stats);
      PutMesh(answer, mesh);
    }
  } catch (const modeling::SurfaceDefectError& e) {
    error(kSurfaceDefect, 0, e.what());
  } catch (const modeling::TetgenError& e) {
    error(kTetgen, e.code(), e.what());
  } catch (const modeling::TetMeshingCancelled& e) {
    error(kCancelled, 0, e.what());
  } catch (const modeling::CgalMeshCancelled& e) {
    error(kCgalCancelled, 0, e.what());
  } catch (const modeling::CgalMeshError& e) {
    error(kCgal, 0, e.what());
  } catch (const std::invalid_argument& e) {
    error(kInvalidArgument, 0, e.what());
  } catch (const std::bad_alloc&) {
    if (kind == kTetgenRequest)
      error(kTetgen, 1, "TetGen failed: out of memory");
    else if (kind == kFactorRequest)
      error(kRuntime, 0, "CHOLMOD factorisation failed: out of memory");
    else
      error(kCgal, 0, "CGAL meshing failed: out of memory");
  } catch (const std::exception& e) {
    error(kRuntime, 0, e.what());
  }
  return WriteAll(out, answer.bytes()) ? 0 : 1;
}

}  // namespace spidarcad::app
