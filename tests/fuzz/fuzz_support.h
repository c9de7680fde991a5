// Helpers shared by the fuzz harnesses of tests/fuzz: a scratch file for readers that take a
// path, and a guard that silences std::cout / std::cerr while a harness drives CLI code.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace spidarcad::fuzz {

// A file in a private temporary directory, rewritten with each input; removed at exit.
class ScratchFile {
 public:
  // `name` is the file name inside the directory (its extension picks the reader's format).
  explicit ScratchFile(const std::string& name) {
    const char* tmp = std::getenv("TMPDIR");
    std::string pattern =
        std::string(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") + "/spidarcad-fuzz-XXXXXX";
    if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    dir_ = pattern;
    path_ = dir_ + "/" + name;
  }
  ~ScratchFile() {
    std::remove(path_.c_str());
    rmdir(dir_.c_str());
  }
  ScratchFile(const ScratchFile&) = delete;
  ScratchFile& operator=(const ScratchFile&) = delete;

  // Replaces the file's content with `size` bytes at `data`; returns the path.
  const std::string& Write(const std::uint8_t* data, std::size_t size) {
    std::FILE* f = std::fopen(path_.c_str(), "wb");
    if (f == nullptr) throw std::runtime_error("cannot write " + path_);
    if (size > 0 && std::fwrite(data, 1, size, f) != size) {
      std::fclose(f);
      throw std::runtime_error("short write to " + path_);
    }
    std::fclose(f);
    return path_;
  }
  const std::string& path() const { return path_; }

 private:
  std::string dir_;
  std::string path_;
};

// While alive: std::cin reads `input`, std::cout and std::cerr go nowhere.
class RedirectedStdio {
 public:
  explicit RedirectedStdio(const std::string& input)
      : in_(input),
        old_in_(std::cin.rdbuf(in_.rdbuf())),
        old_out_(std::cout.rdbuf(sink_.rdbuf())),
        old_err_(std::cerr.rdbuf(sink_.rdbuf())) {
    std::cin.clear();
  }
  ~RedirectedStdio() {
    std::cin.rdbuf(old_in_);
    std::cout.rdbuf(old_out_);
    std::cerr.rdbuf(old_err_);
    std::cin.clear();
    std::cout.clear();
    std::cerr.clear();
  }
  RedirectedStdio(const RedirectedStdio&) = delete;
  RedirectedStdio& operator=(const RedirectedStdio&) = delete;
  // What was written to std::cout and std::cerr.
  std::string output() const { return sink_.str(); }

 private:
  std::istringstream in_;
  std::ostringstream sink_;
  std::streambuf* old_in_;
  std::streambuf* old_out_;
  std::streambuf* old_err_;
};

// Stops the process the way libFuzzer recognises as a crash, with a message: a property that
// every accepted input must have was broken.
[[noreturn]] inline void Violated(const char* harness, const std::string& what) {
  std::fprintf(stderr, "%s: property violated: %s\n", harness, what.c_str());
  std::abort();
}

}  // namespace spidarcad::fuzz
