// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The cache files' byte writer and reader, checksum, and MapCacheFile's refusals: each way a file
// can be wrong is told apart, and an absent file is a plain miss.
#include "spidarcad/fem/cache_file.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace spidarcad::fem {
namespace {

constexpr char kMagic[8] = {'S', 'P', 'D', 'T', 'E', 'S', 'T', '1'};

std::filesystem::path Scratch(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::path(::testing::TempDir()) / "spidarcad-cache-file-test";
  std::filesystem::create_directories(dir);
  return dir / name;
}

TEST(CacheFile, WriterAndReaderRoundTripIncludingEmptyVectors) {
  ByteWriter w;
  w.Put(std::int32_t{-7});
  w.PutVector(std::vector<double>{1.5, -2.25});
  w.PutVector(std::vector<int>{});  // an empty vector's data() may be null
  w.PutArray(static_cast<const double*>(nullptr), 0);
  w.Put(std::uint64_t{42});
  ByteReader r(w.bytes().data(), w.bytes().size());
  std::int32_t i = 0;
  std::vector<double> d;
  std::vector<int> empty = {3};
  std::uint64_t u = 0;
  ASSERT_TRUE(r.Get(&i));
  ASSERT_TRUE(r.GetVector(&d));
  ASSERT_TRUE(r.GetVector(&empty));
  ASSERT_TRUE(r.GetArray(static_cast<double*>(nullptr), 0));
  ASSERT_TRUE(r.Get(&u));
  EXPECT_EQ(i, -7);
  EXPECT_EQ(d, (std::vector<double>{1.5, -2.25}));
  EXPECT_TRUE(empty.empty());
  EXPECT_EQ(u, 42u);
  EXPECT_EQ(r.remaining(), 0u);
  // Past the end every read fails, and a count larger than what is left allocates nothing.
  EXPECT_FALSE(r.Get(&u));
  ByteWriter lie;
  lie.Put(std::uint64_t{1} << 60);  // a count of 2^60 doubles, and no doubles
  ByteReader liar(lie.bytes().data(), lie.bytes().size());
  EXPECT_FALSE(liar.GetVector(&d));
}

TEST(CacheFile, ChecksumSeesEveryByteAndItsPlace) {
  std::vector<unsigned char> bytes(1000);
  for (std::size_t k = 0; k < bytes.size(); ++k) bytes[k] = static_cast<unsigned char>(k * 7);
  const std::uint64_t h = WordChecksum64(bytes.data(), bytes.size());
  for (std::size_t k : {std::size_t{0}, std::size_t{5}, std::size_t{31}, std::size_t{32},
                        std::size_t{997}, std::size_t{999}}) {
    std::vector<unsigned char> flipped = bytes;
    flipped[k] ^= 1;
    EXPECT_NE(WordChecksum64(flipped.data(), flipped.size()), h) << "byte " << k;
  }
  // Two words swapped between lanes, and a shorter run with the same prefix.
  std::vector<unsigned char> swapped = bytes;
  std::swap_ranges(swapped.begin(), swapped.begin() + 8, swapped.begin() + 8);
  EXPECT_NE(WordChecksum64(swapped.data(), swapped.size()), h);
  EXPECT_NE(WordChecksum64(bytes.data(), bytes.size() - 1), h);
  EXPECT_EQ(WordChecksum64(bytes.data(), bytes.size()), h);
}

TEST(CacheFile, MappedFileIsTheBodyWrittenAndEachDefectIsNamed) {
  const std::filesystem::path path = Scratch("good.bin");
  const std::vector<unsigned char> body = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};
  std::string why;
  ASSERT_TRUE(WriteCacheFile(path, kMagic, body, &why)) << why;
  {
    const auto mapped = MapCacheFile(path, kMagic, &why);
    ASSERT_TRUE(mapped.has_value()) << why;
    EXPECT_EQ(std::vector<unsigned char>(mapped->data(), mapped->data() + mapped->size()), body);
  }
  // Absent: a miss, said as "absent" (also under a path through a file).
  EXPECT_FALSE(MapCacheFile(Scratch("missing.bin"), kMagic, &why).has_value());
  EXPECT_EQ(why, "absent");
  EXPECT_FALSE(MapCacheFile(path / "below-a-file", kMagic, &why).has_value());
  EXPECT_EQ(why, "absent");
  // Another magic.
  constexpr char kOther[8] = {'S', 'P', 'D', 'O', 'T', 'H', 'E', 'R'};
  EXPECT_FALSE(MapCacheFile(path, kOther, &why).has_value());
  EXPECT_NE(why.find("bad magic"), std::string::npos) << why;
  EXPECT_NE(why.find(path.string()), std::string::npos) << why;
  // A flipped byte of the body.
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(10);
    f.put('\x7f');
  }
  EXPECT_FALSE(MapCacheFile(path, kMagic, &why).has_value());
  EXPECT_NE(why.find("checksum mismatch"), std::string::npos) << why;
  // Shorter than a magic and a checksum.
  std::filesystem::resize_file(path, 12);
  EXPECT_FALSE(MapCacheFile(path, kMagic, &why).has_value());
  EXPECT_NE(why.find("truncated (12 bytes)"), std::string::npos) << why;
  // A directory that cannot be made: the writer says so, nothing thrown.
  EXPECT_FALSE(WriteCacheFile(path / "sub" / "x.bin", kMagic, body, &why));
  EXPECT_NE(why.find("cannot create cache directory"), std::string::npos) << why;
  std::filesystem::remove_all(path.parent_path());
}

// Least recently used first, down to the bound; never a file used since the run began, nor a
// file of another kind.
TEST(CacheFile, PruneRemovesTheLeastRecentlyUsedDownToTheBound) {
  const std::filesystem::path dir = Scratch("prune");
  std::filesystem::create_directories(dir);
  const auto now = std::filesystem::file_time_type::clock::now();
  auto make = [&](const std::string& name, int age_s) {
    std::ofstream(dir / name) << std::string(100, 'x');
    std::filesystem::last_write_time(dir / name, now - std::chrono::seconds(age_s));
  };
  make("a.block", 40);
  make("b.slab", 30);
  make("c.plane", 20);
  make("d.block", 10);
  make("notes.txt", 50);
  const std::vector<std::string> kinds = {".block", ".plane", ".slab"};
  const PruneStats within = PruneCacheDirectory(dir, 400, kinds, now - std::chrono::seconds(15));
  EXPECT_EQ(within.removed_files, 0);
  EXPECT_EQ(within.kept_bytes, 400u);
  const PruneStats cut = PruneCacheDirectory(dir, 250, kinds, now - std::chrono::seconds(15));
  EXPECT_EQ(cut.removed_files, 2);
  EXPECT_EQ(cut.removed_bytes, 200u);
  EXPECT_EQ(cut.kept_bytes, 200u);
  EXPECT_FALSE(std::filesystem::exists(dir / "a.block"));
  EXPECT_FALSE(std::filesystem::exists(dir / "b.slab"));
  EXPECT_TRUE(std::filesystem::exists(dir / "c.plane"));
  // Down to nothing: the file newer than the protection stays, as does the other kind.
  const PruneStats all = PruneCacheDirectory(dir, 0, kinds, now - std::chrono::seconds(15));
  EXPECT_EQ(all.removed_files, 1);
  EXPECT_TRUE(std::filesystem::exists(dir / "d.block"));
  EXPECT_TRUE(std::filesystem::exists(dir / "notes.txt"));
  // Reading a file marks it used: an old file read now is protected.
  const std::vector<unsigned char> body = {1, 2, 3};
  ASSERT_TRUE(WriteCacheFile(dir / "e.block", kMagic, body));
  std::filesystem::last_write_time(dir / "e.block", now - std::chrono::seconds(100));
  ASSERT_TRUE(MapCacheFile(dir / "e.block", kMagic).has_value());
  EXPECT_GE(std::filesystem::last_write_time(dir / "e.block"), now - std::chrono::seconds(15));
  EXPECT_EQ(PruneCacheDirectory(dir, 0, kinds, now - std::chrono::seconds(15)).removed_files, 0);
  // A directory that is not there: nothing, no throw.
  EXPECT_EQ(PruneCacheDirectory(dir / "none", 0, kinds, now).removed_files, 0);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace spidarcad::fem
