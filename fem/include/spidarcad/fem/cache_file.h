// Binary cache files: a byte writer and reader for trivially copyable values, and whole files
// written under a temporary name then renamed (a reader never sees half a file) with a trailing
// checksum, read back only when magic, size and checksum are right. Used by the on-disk caches
// (precomputed columns, substructure block factors, slab meshes). Values are stored as this
// machine holds them (little-endian on every platform spidarcad builds for).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <initializer_list>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace spidarcad::fem {

// Appends raw bytes of trivially copyable values to a byte buffer.
class ByteWriter {
 public:
  template <typename T>
  void Put(const T& v) {
    const auto* p = reinterpret_cast<const unsigned char*>(&v);
    bytes_.insert(bytes_.end(), p, p + sizeof(T));
  }
  template <typename T>
  void PutArray(const T* v, std::size_t n) {
    if (n == 0) return;
    const auto* p = reinterpret_cast<const unsigned char*>(v);
    bytes_.insert(bytes_.end(), p, p + sizeof(T) * n);
  }
  // A u64 count, then the elements.
  template <typename T>
  void PutVector(const std::vector<T>& v) {
    Put(static_cast<std::uint64_t>(v.size()));
    PutArray(v.data(), v.size());
  }
  std::vector<unsigned char>& bytes() { return bytes_; }

 private:
  std::vector<unsigned char> bytes_;
};

// Reads trivially copyable values from a byte buffer; every call fails (returns false) past its
// end, so a truncated or corrupt count never allocates more than the buffer holds.
class ByteReader {
 public:
  ByteReader(const unsigned char* data, std::size_t size) : data_(data), size_(size) {}
  template <typename T>
  bool Get(T* v) {
    if (size_ - pos_ < sizeof(T)) return false;
    std::memcpy(v, data_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  template <typename T>
  bool GetArray(T* v, std::size_t n) {
    if (n == 0) return true;  // (v may be null then: the data() of an empty vector)
    if (n > (size_ - pos_) / sizeof(T)) return false;
    std::memcpy(v, data_ + pos_, sizeof(T) * n);
    pos_ += sizeof(T) * n;
    return true;
  }
  // A vector written by ByteWriter::PutVector.
  template <typename T>
  bool GetVector(std::vector<T>* v) {
    std::uint64_t n = 0;
    if (!Get(&n) || n > remaining() / sizeof(T)) return false;
    v->resize(n);
    return GetArray(v->data(), n);
  }
  std::size_t remaining() const { return size_ - pos_; }

 private:
  const unsigned char* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

// Checksum of a file's bytes: FNV-1a 64 run on four interleaved lanes of eight-byte words (the
// tail byte by byte), the lanes folded together at the end: several gigabytes a second, where
// the byte-wise hash manages a few hundred megabytes.
std::uint64_t WordChecksum64(const void* data, std::size_t size);

// "0123456789abcdef": 16 lower-case hex digits of a key (cache file names).
std::string HexKey(std::uint64_t key);

// Writes the pieces (pointer, bytes), one after the other, to `path` through a temporary file in
// the same directory (created if missing) renamed over it, so that a reader never sees half a
// file. Returns false with the reason in *error (when given) if it cannot be written.
bool WriteFileAtomically(const std::filesystem::path& path,
                         std::initializer_list<std::pair<const void*, std::size_t>> pieces,
                         std::string* error = nullptr);

// Writes magic (8 bytes), then `body`, then WordChecksum64 of both, to `path` through a
// temporary file in the same directory (created if missing) renamed over it. Returns false with
// the reason in *error (when given) if the directory or file cannot be written.
bool WriteCacheFile(const std::filesystem::path& path, const char (&magic)[8],
                    const std::vector<unsigned char>& body, std::string* error = nullptr);

// A cache file mapped into memory (read only), its body checked: see MapCacheFile.
class MappedCacheFile {
 public:
  MappedCacheFile(MappedCacheFile&& other) noexcept;
  MappedCacheFile& operator=(MappedCacheFile&&) = delete;
  MappedCacheFile(const MappedCacheFile&) = delete;
  MappedCacheFile& operator=(const MappedCacheFile&) = delete;
  ~MappedCacheFile();
  // The body: the bytes between the magic and the checksum.
  const unsigned char* data() const { return base_ + 8; }
  std::size_t size() const { return length_ - 16; }

 private:
  friend std::optional<MappedCacheFile> MapCacheFile(const std::filesystem::path&,
                                                     const char (&)[8], std::string*);
  MappedCacheFile(const unsigned char* base, std::size_t length) : base_(base), length_(length) {}
  const unsigned char* base_;
  std::size_t length_;
};

// The body of a file written by WriteCacheFile with the same magic, mapped (no copy: a reader
// copies what it keeps). A file that passes is marked as used now (its modification time, for
// PruneCacheDirectory). Nothing, with the reason in *reason (when given; "absent" when there
// is no file, so callers can tell a miss from a bad file), when it is absent, unreadable, too
// short, of another magic or fails its checksum.
std::optional<MappedCacheFile> MapCacheFile(const std::filesystem::path& path,
                                            const char (&magic)[8], std::string* reason = nullptr);

// What PruneCacheDirectory did.
struct PruneStats {
  int removed_files = 0;
  std::uintmax_t removed_bytes = 0;
  // Bytes of the cache files left (of the extensions asked for).
  std::uintmax_t kept_bytes = 0;
};

// Keeps the cache files of `directory` whose names end in one of `extensions` (".block", ...)
// within `max_bytes` together, removing the least recently used first: by modification time,
// which MapCacheFile sets on every file it reads. A file modified at or after `protect_since` (a
// file this run read or wrote) is never removed, even over the bound. Other files are not
// touched. A file that vanishes meanwhile (another run pruned it) is skipped; nothing throws.
PruneStats PruneCacheDirectory(const std::filesystem::path& directory, std::uintmax_t max_bytes,
                               const std::vector<std::string>& extensions,
                               std::filesystem::file_time_type protect_since);

}  // namespace spidarcad::fem
