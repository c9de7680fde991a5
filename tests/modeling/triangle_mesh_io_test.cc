// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/triangle_mesh_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>
#include <string>
#include <tuple>
#include <vector>

namespace spidarcad::modeling {
namespace {

std::string OutPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/" + name;
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// A torus meshed by MeshSurface: thousands of vertices with irrational coordinates.
TriangleMesh Torus() {
  const CompiledSolid torus = CompiledSolid::Compile(ImplicitNode(TorusParams{0.04, 0.012}));
  SurfaceMeshSettings s;
  s.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.06, -0.06, -0.02), Eigen::Vector3d(0.06, 0.06, 0.02));
  s.cell_size = 0.004;
  return MeshSurface(torus, s);
}

// Expects the error to carry file and location and a message containing `what`.
template <typename F>
void ExpectFileError(F f, const std::string& file, long line, long byte_offset,
                     const std::string& what) {
  try {
    f();
    ADD_FAILURE() << "no MeshFileError for " << file;
  } catch (const MeshFileError& e) {
    EXPECT_EQ(e.file(), file);
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.byte_offset(), byte_offset) << e.what();
    EXPECT_NE(e.message().find(what), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(file), std::string::npos);
  }
}

TEST(TriangleMeshIo, ObjAndPlyRoundTripExactly) {
  const TriangleMesh mesh = Torus();
  ASSERT_GT(mesh.triangles.cols(), 1000);
  for (const auto& [name, format] : {std::pair{"t.obj", MeshFileFormat::kObj},
                                     std::pair{"t_ascii.ply", MeshFileFormat::kPlyAscii},
                                     std::pair{"t_binary.ply", MeshFileFormat::kPlyBinary}}) {
    WriteTriangleMesh(mesh, OutPath(name), format);
    const TriangleMesh back = ReadTriangleMesh(OutPath(name));
    EXPECT_EQ(back.vertices, mesh.vertices) << name;  // 17 digits or raw doubles: exact
    EXPECT_EQ(back.triangles, mesh.triangles) << name;
  }
}

// Found by the sanitizer pass (docs/sanitizers.md): binary PLY handed the empty vertex matrix's
// null data pointer to fwrite, undefined behaviour that UBSan reports (nonnull argument).
TEST(TriangleMeshIo, EmptyMeshRoundTripsThroughObjAndPly) {
  const TriangleMesh empty;
  ASSERT_EQ(empty.vertices.data(), nullptr);
  for (const auto& [name, format] : {std::pair{"empty.obj", MeshFileFormat::kObj},
                                     std::pair{"empty_ascii.ply", MeshFileFormat::kPlyAscii},
                                     std::pair{"empty_binary.ply", MeshFileFormat::kPlyBinary}}) {
    WriteTriangleMesh(empty, OutPath(name), format);
    const TriangleMesh back = ReadTriangleMesh(OutPath(name));
    EXPECT_EQ(back.vertices.cols(), 0) << name;
    EXPECT_EQ(back.triangles.cols(), 0) << name;
  }
}

TEST(TriangleMeshIo, StlRoundTripsToFloatPrecisionAndWeldsVertices) {
  const TriangleMesh mesh = Torus();
  for (const auto& [name, format, as_float] :
       {std::tuple{"t_ascii.stl", MeshFileFormat::kStlAscii, false},
        std::tuple{"t_binary.stl", MeshFileFormat::kStlBinary, true}}) {
    // What the file can hold: corner positions (floats for binary). Corners at one position are
    // one vertex, and triangles with coinciding corners cannot be represented.
    const bool single = as_float;
    auto stored = [&mesh, single](int v) {
      std::array<double, 3> p;
      for (int i = 0; i < 3; ++i)
        p[i] = single ? static_cast<double>(static_cast<float>(mesh.vertices(i, v)))
                      : mesh.vertices(i, v);
      return p;
    };
    std::set<std::array<double, 3>> distinct;
    std::vector<Eigen::Index> kept;
    for (Eigen::Index f = 0; f < mesh.triangles.cols(); ++f) {
      const auto a = stored(mesh.triangles(0, f)), b = stored(mesh.triangles(1, f)),
                 c = stored(mesh.triangles(2, f));
      if (a == b || b == c || a == c) continue;
      kept.push_back(f);
      distinct.insert({a, b, c});
    }
    WriteTriangleMesh(mesh, OutPath(name), format);
    const TriangleMesh back = ReadTriangleMesh(OutPath(name));
    EXPECT_EQ(back.vertices.cols(), static_cast<Eigen::Index>(distinct.size())) << name;
    ASSERT_EQ(back.triangles.cols(), static_cast<Eigen::Index>(kept.size())) << name;
    for (size_t f = 0; f < kept.size(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const auto expected = stored(mesh.triangles(k, kept[f]));
        ASSERT_EQ(Eigen::Vector3d(back.vertices.col(back.triangles(k, f))),
                  Eigen::Vector3d(expected[0], expected[1], expected[2]))
            << name << " triangle " << f;
      }
    }
    EXPECT_NEAR(MeshVolume(back), MeshVolume(mesh), 1e-6 * MeshVolume(mesh)) << name;
  }
}

TEST(TriangleMeshIo, ReadsHandWrittenObjWithQuadsNegativeAndSlashedIndices) {
  const std::string path = OutPath("quad.obj");
  WriteText(path,
            "# a unit square as a quad and one more triangle\nmtllib x.mtl\nv 0 0 0\nv 1 0 0\nv 1 "
            "1 0\nv 0 1 0\n"
            "vt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1 4/1/1\nv 0.5 0.5 1\nf -5 -4 -1\n");
  const TriangleMesh m = ReadTriangleMesh(path);
  ASSERT_EQ(m.vertices.cols(), 5);
  ASSERT_EQ(m.triangles.cols(), 3);
  EXPECT_EQ(m.triangles.col(0), Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(m.triangles.col(1), Eigen::Vector3i(0, 2, 3));
  EXPECT_EQ(m.triangles.col(2), Eigen::Vector3i(0, 1, 4));
  EXPECT_EQ(m.vertices.col(4), Eigen::Vector3d(0.5, 0.5, 1));
}

TEST(TriangleMeshIo, ReadsPlyWithExtraPropertiesAndElements) {
  const std::string path = OutPath("extra.ply");
  WriteText(path,
            "ply\nformat ascii 1.0\ncomment colours and an edge element\nelement vertex "
            "4\nproperty float x\n"
            "property uchar red\nproperty float y\nproperty float z\nelement face 1\nproperty "
            "uchar flags\n"
            "property list uchar int vertex_indices\nelement edge 1\nproperty int "
            "vertex1\nproperty int vertex2\nend_header\n"
            "0 255 0 0\n2 0 0 0\n2 7 2 0\n0 9 2 0.5\n3 4 0 1 2 3\n0 1\n");
  const TriangleMesh m = ReadTriangleMesh(path);
  ASSERT_EQ(m.vertices.cols(), 4);
  EXPECT_EQ(m.vertices.col(3), Eigen::Vector3d(0, 2, 0.5));
  ASSERT_EQ(m.triangles.cols(), 2);
  EXPECT_EQ(m.triangles.col(1), Eigen::Vector3i(0, 2, 3));
}

TEST(TriangleMeshIo, BadStlNamesLineOrByteOffset) {
  const std::string ascii = OutPath("bad_ascii.stl");
  WriteText(ascii,
            "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 zero\nvertex 0 1 "
            "0\nendloop\nendfacet\nendsolid\n");
  ExpectFileError([&] { ReadTriangleMesh(ascii); }, ascii, 5, -1, "'zero'");
  const std::string missing = OutPath("bad_missing.stl");
  WriteText(missing,
            "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 "
            "0\nendloop\nendfacet\nendsolid\n");
  ExpectFileError([&] { ReadTriangleMesh(missing); }, missing, 6, -1, "expected 'vertex'");
  // Binary: a header announcing 2 triangles followed by only one.
  std::string data(84 + 50, '\0');
  const uint32_t two = 2;
  std::memcpy(&data[80], &two, 4);
  const std::string binary = OutPath("bad_binary.stl");
  WriteText(binary, data);
  ExpectFileError([&] { ReadTriangleMesh(binary); }, binary, 0, 80, "announces 2 triangles");
}

TEST(TriangleMeshIo, BadObjAndPlyNameLineOrByteOffset) {
  const std::string obj = OutPath("bad.obj");
  WriteText(obj, "v 0 0 0\nv 1 0 0\nf 1 2 3\n");
  ExpectFileError([&] { ReadTriangleMesh(obj); }, obj, 3, -1, "index 3 refers to no vertex");
  const std::string obj2 = OutPath("bad2.obj");
  WriteText(obj2, "v 0 0\n");
  ExpectFileError([&] { ReadTriangleMesh(obj2); }, obj2, 1, -1, "3 coordinates");
  const std::string ply = OutPath("bad_index.ply");
  WriteText(ply,
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty "
            "float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 "
            "0\n3 0 1 7\n");
  ExpectFileError([&] { ReadTriangleMesh(ply); }, ply, 13, -1, "vertex index 7");
  const std::string big = OutPath("bad_format.ply");
  WriteText(big, "ply\nformat binary_big_endian 1.0\nend_header\n");
  ExpectFileError([&] { ReadTriangleMesh(big); }, big, 2, -1, "binary_big_endian");
  // Binary PLY cut short inside the second vertex: header of 175 bytes, then 12 + 4 bytes.
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  std::string body(16, '\0');
  const std::string cut = OutPath("bad_cut.ply");
  WriteText(cut, header + body);
  ExpectFileError([&] { ReadTriangleMesh(cut); }, cut, 0, static_cast<long>(header.size() + 16),
                  "vertex 1 property y");
}

TEST(TriangleMeshIo, UnknownExtensionAndMissingFileAreErrors) {
  ExpectFileError([] { ReadTriangleMesh("/nonexistent/x.stl"); }, "/nonexistent/x.stl", 0, -1,
                  "cannot open");
  ExpectFileError([] { ReadTriangleMesh("mesh.3ds"); }, "mesh.3ds", 0, -1,
                  "unknown mesh file extension");
  TriangleMesh bad;
  bad.vertices.setZero(3, 3);
  bad.triangles.resize(3, 1);
  bad.triangles << 0, 1, 3;
  EXPECT_THROW(WriteTriangleMesh(bad, OutPath("bad_out.obj")), std::invalid_argument);
}

// The regressions below were found by the ply fuzz harness; each input is also replayed from
// tests/fuzz/regressions/ply/ (ctest -L fuzz).

// A list count far beyond long's range was converted to long before it was checked (undefined
// behaviour, caught by UBSan): it must be refused with its line.
TEST(TriangleMeshIo, PlyListCountBeyondLongIsAnErrorWithItsLine) {
  const std::string path = OutPath("list_count_beyond_long.ply");
  WriteText(path,
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
            "0 0 0\n1 0 0\n0 1 0\n1e300 0 1 2\n");
  ExpectFileError([&] { ReadTriangleMesh(path); }, path, 13, -1, "bad list count");
}

// Entries of a list other than the face corners were converted to int whatever their value
// (undefined behaviour beyond int's range): they are skipped, and the mesh reads.
TEST(TriangleMeshIo, PlySkipsEntriesOfOtherListsWhateverTheirValue) {
  const std::string path = OutPath("other_list_entry_beyond_int.ply");
  WriteText(path,
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nproperty list uchar double weights\nelement face 1\n"
            "property list uchar int vertex_indices\nend_header\n"
            "0 0 0 2 1e300 -1e300\n1 0 0 0\n0 1 0 1 -3e9\n3 0 1 2\n");
  const TriangleMesh mesh = ReadTriangleMesh(path);
  ASSERT_EQ(mesh.vertices.cols(), 3);
  ASSERT_EQ(mesh.triangles.cols(), 1);
  EXPECT_EQ(mesh.vertices.col(2), Eigen::Vector3d(0, 1, 0));
  EXPECT_EQ(mesh.triangles.col(0), Eigen::Vector3i(0, 1, 2));
}

// An element with no properties and a count of 2^63 - 1 made the reader spin through every
// (empty) item: it has no data, so it is passed over at once.
TEST(TriangleMeshIo, PlyElementWithoutPropertiesIsPassedOverWhateverItsCount) {
  const std::string path = OutPath("element_without_properties.ply");
  WriteText(path,
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement nothing 9223372036854775807\nelement face 1\n"
            "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  const TriangleMesh mesh = ReadTriangleMesh(path);
  EXPECT_EQ(mesh.vertices.cols(), 3);
  EXPECT_EQ(mesh.triangles.cols(), 1);
}

// Subnormal coordinates (found by the ply fuzz harness, tests/fuzz/regressions/ply/
// subnormal_coordinate.ply): binary PLY and STL carry them, but the text readers refused the
// text the writers print for them, because strtod flags underflow with ERANGE.
TEST(TriangleMeshIo, SubnormalCoordinatesRoundTripThroughTheTextFormats) {
  TriangleMesh mesh;
  mesh.vertices.resize(3, 3);
  const double tiny = std::numeric_limits<double>::denorm_min();
  mesh.vertices << tiny, 1, 0, 3.3527533497251303e-312, 0, 1, -2.1219957909652723e-314, 0, 0;
  mesh.triangles.resize(3, 1);
  mesh.triangles << 0, 1, 2;
  ASSERT_LT(std::abs(mesh.vertices(1, 0)), std::numeric_limits<double>::min());  // subnormal
  for (const auto& [name, format] :
       {std::pair{"subnormal.obj", MeshFileFormat::kObj},
        std::pair{"subnormal_ascii.ply", MeshFileFormat::kPlyAscii},
        std::pair{"subnormal_binary.ply", MeshFileFormat::kPlyBinary}}) {
    WriteTriangleMesh(mesh, OutPath(name), format);
    const TriangleMesh back = ReadTriangleMesh(OutPath(name));
    EXPECT_EQ(back.vertices, mesh.vertices) << name;
    EXPECT_EQ(back.triangles, mesh.triangles) << name;
  }
}

}  // namespace
}  // namespace spidarcad::modeling
