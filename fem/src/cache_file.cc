// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/cache_file.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <fstream>
#include <system_error>

namespace spidarcad::fem {
namespace {

// Bytes per read or write call.
constexpr std::size_t kChunk = std::size_t{1} << 22;

}  // namespace

std::uint64_t WordChecksum64(const void* data, std::size_t size) {
  constexpr std::uint64_t kPrime = 1099511628211ull, kBasis = 14695981039346656037ull;
  // Four independent multiply chains keep the multiplier busy (one chain waits on each
  // product's latency).
  std::uint64_t h[4] = {kBasis, kBasis ^ 1, kBasis ^ 2, kBasis ^ 3};
  const auto* p = static_cast<const unsigned char*>(data);
  std::size_t i = 0;
  for (; i + 32 <= size; i += 32) {
    std::uint64_t w[4];
    std::memcpy(w, p + i, 32);
    for (int l = 0; l < 4; ++l) h[l] = (h[l] ^ w[l]) * kPrime;
  }
  std::uint64_t out = kBasis;
  for (int l = 0; l < 4; ++l)
    for (int k = 0; k < 8; ++k) out = (out ^ ((h[l] >> (8 * k)) & 0xff)) * kPrime;
  for (; i < size; ++i) out = (out ^ p[i]) * kPrime;
  return out;
}

std::string HexKey(std::uint64_t key) {
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(key));
  return buf;
}

bool WriteFileAtomically(const std::filesystem::path& path,
                         std::initializer_list<std::pair<const void*, std::size_t>> pieces,
                         std::string* error) {
  auto fail = [&](const std::string& why) {
    if (error) *error = why;
    return false;
  };
  std::error_code ec;
  const std::filesystem::path dir = path.parent_path();
  if (!dir.empty()) {
    std::filesystem::create_directories(dir, ec);
    if (ec) return fail("cannot create cache directory " + dir.string() + ": " + ec.message());
  }
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path temp = path.string() + ".tmp." + std::to_string(::getpid()) + "." +
                                     std::to_string(counter.fetch_add(1));
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) return fail("cannot open " + temp.string() + " for writing");
    // In pieces: one write of hundreds of megabytes runs at a tenth of the speed (measured on
    // Linux 6: 2.8 s against 0.12 s for 470 MB).
    for (const auto& [data, size] : pieces) {
      const auto* bytes = static_cast<const char*>(data);
      for (std::size_t at = 0; at < size && out; at += kChunk)
        out.write(bytes + at, static_cast<std::streamsize>(std::min(kChunk, size - at)));
    }
    out.flush();
    if (!out) {
      out.close();
      std::filesystem::remove(temp, ec);
      return fail("cannot write " + temp.string() + " (disk full?)");
    }
  }
  std::filesystem::rename(temp, path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(temp, ignored);
    return fail("cannot rename " + temp.string() + " to " + path.string() + ": " + ec.message());
  }
  return true;
}

bool WriteCacheFile(const std::filesystem::path& path, const char (&magic)[8],
                    const std::vector<unsigned char>& body, std::string* error) {
  // The checksum covers the body (the magic is checked on its own).
  const std::uint64_t h = WordChecksum64(body.data(), body.size());
  return WriteFileAtomically(path, {{magic, 8}, {body.data(), body.size()}, {&h, sizeof(h)}},
                             error);
}

MappedCacheFile::MappedCacheFile(MappedCacheFile&& other) noexcept
    : base_(other.base_), length_(other.length_) {
  other.base_ = nullptr;
  other.length_ = 0;
}

MappedCacheFile::~MappedCacheFile() {
  if (base_ != nullptr) ::munmap(const_cast<unsigned char*>(base_), length_);
}

std::optional<MappedCacheFile> MapCacheFile(const std::filesystem::path& path,
                                            const char (&magic)[8], std::string* reason) {
  auto fail = [&](const std::string& why) -> std::optional<MappedCacheFile> {
    if (reason) *reason = why;
    return std::nullopt;
  };
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT || errno == ENOTDIR) return fail("absent");
    return fail(path.string() + ": unreadable (" + std::strerror(errno) + ")");
  }
  struct stat st;
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    return fail(path.string() + ": unreadable");
  }
  const auto length = static_cast<std::size_t>(st.st_size);
  if (length < 16) {
    ::close(fd);
    return fail(path.string() + ": truncated (" + std::to_string(length) + " bytes)");
  }
  // MAP_POPULATE maps the whole file in one go (no page fault per 4 KiB on the way through).
  void* base = ::mmap(nullptr, length, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
  ::close(fd);
  if (base == MAP_FAILED)
    return fail(path.string() + ": cannot map (" + std::strerror(errno) + ")");
  MappedCacheFile file(static_cast<const unsigned char*>(base), length);
  const auto* bytes = static_cast<const unsigned char*>(base);
  if (std::memcmp(bytes, magic, 8) != 0)
    return fail(path.string() + ": not a spidarcad " + std::string(magic, 8) + " file (bad magic)");
  std::uint64_t stored = 0;
  std::memcpy(&stored, bytes + length - 8, 8);
  if (WordChecksum64(file.data(), file.size()) != stored)
    return fail(path.string() + ": checksum mismatch (corrupt or truncated)");
  ::utimensat(AT_FDCWD, path.c_str(), nullptr, 0);  // used now (a read-only directory: no matter)
  return file;
}

PruneStats PruneCacheDirectory(const std::filesystem::path& directory, std::uintmax_t max_bytes,
                               const std::vector<std::string>& extensions,
                               std::filesystem::file_time_type protect_since) {
  struct Entry {
    std::filesystem::file_time_type time;
    std::uintmax_t bytes;
    std::filesystem::path path;
  };
  std::vector<Entry> entries;
  PruneStats stats;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(directory, ec), end; !ec && it != end;
       it.increment(ec)) {
    const std::string ext = it->path().extension().string();
    if (std::find(extensions.begin(), extensions.end(), ext) == extensions.end()) continue;
    std::error_code e1, e2;
    const auto time = it->last_write_time(e1);
    const auto bytes = it->file_size(e2);
    if (e1 || e2) continue;  // gone meanwhile
    entries.push_back({time, bytes, it->path()});
    stats.kept_bytes += bytes;
  }
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return a.time < b.time; });
  for (const Entry& e : entries) {
    if (stats.kept_bytes <= max_bytes || e.time >= protect_since) break;
    std::error_code removed;
    if (std::filesystem::remove(e.path, removed) && !removed) {
      ++stats.removed_files;
      stats.removed_bytes += e.bytes;
    }
    stats.kept_bytes -= e.bytes;  // gone, by this run or another
  }
  return stats;
}

}  // namespace spidarcad::fem
