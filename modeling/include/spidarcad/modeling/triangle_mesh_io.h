// Triangle mesh files: STL (ASCII and binary), Wavefront OBJ, PLY (ASCII and binary
// little-endian), read and written. The format is chosen from the file extension (.stl, .obj,
// .ply, case-insensitive); STL and PLY readers detect ASCII or binary themselves.
//
// Units: coordinates are written and read as they are (the app keeps metres). STL stores
// 32-bit floats (so a round trip rounds to about 7 digits) and no shared vertices: the reader
// welds vertices with identical coordinates and drops facets whose corners coincide (zero
// area; they have no meaning without indices). OBJ faces with more than three corners are
// fanned into triangles; OBJ texture and normal indices are ignored. PLY needs an element
// "vertex" with float/double properties x, y, z and an element "face" with a list property
// vertex_indices (or vertex_index); other properties and elements are skipped.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <stdexcept>
#include <string>

#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::modeling {

// File formats of ReadTriangleMesh and WriteTriangleMesh.
enum class MeshFileFormat { kStlAscii, kStlBinary, kObj, kPlyAscii, kPlyBinary };

// A malformed or unreadable mesh file: the file, where (a 1-based line for text, a byte offset
// for binary data, both 0 when not applicable), and what was wrong.
class MeshFileError : public std::runtime_error {
 public:
  // line is 1-based (0: not a text position); byte_offset is used when line == 0 and >= 0.
  MeshFileError(const std::string& file, long line, long byte_offset, const std::string& what);
  const std::string& file() const { return file_; }
  long line() const { return line_; }
  long byte_offset() const { return byte_offset_; }
  // What was wrong, without the location prefix of what().
  const std::string& message() const { return message_; }

 private:
  std::string file_;
  long line_;
  long byte_offset_;
  std::string message_;
};

// Reads a triangle mesh; the format follows the extension. Validates every index (in range,
// no repeated corner within a face). Throws MeshFileError.
TriangleMesh ReadTriangleMesh(const std::string& path);

// Writes mesh to path in the given format. Throws MeshFileError if the file cannot be written
// and std::invalid_argument if a triangle index is out of range.
void WriteTriangleMesh(const TriangleMesh& mesh, const std::string& path, MeshFileFormat format);

// Writes mesh in the format the extension names: .stl binary, .obj, .ply binary.
void WriteTriangleMesh(const TriangleMesh& mesh, const std::string& path);

}  // namespace spidarcad::modeling
