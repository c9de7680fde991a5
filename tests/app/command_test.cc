// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// ImportMeshCommand (doc/command.h): a mesh read from a file lands as one undoable mesh object.
// (The other commands are covered by document_test.cc, history_test.cc and clipboard_test.cc.)
#include "doc/command.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>

#include "doc/document.h"

namespace spidarcad::app {
namespace {

std::shared_ptr<const modeling::TriangleMesh> Triangle() {
  auto m = std::make_shared<modeling::TriangleMesh>();
  m->vertices.resize(3, 3);
  m->vertices << 0, 1, 0, 0, 0, 1, 0, 0, 0;
  m->triangles.resize(3, 1);
  m->triangles << 0, 1, 2;
  return m;
}

std::shared_ptr<const modeling::TetMesh> Tet() {
  auto m = std::make_shared<modeling::TetMesh>();
  m->nodes.resize(3, 4);
  m->nodes << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  m->tets.resize(4, 1);
  m->tets << 0, 1, 2, 3;
  m->regions = Eigen::VectorXi::Constant(1, 7);
  return m;
}

TEST(ImportMeshCommand, AddsAMeshObjectThatRemembersItsFileAndUndoes) {
  Document doc;
  doc.Execute(std::make_unique<ImportMeshCommand>("part", "/tmp/part.stl", Triangle(), nullptr));
  ASSERT_EQ(doc.objects().size(), 1u);
  const DocObject& o = doc.objects()[0];
  EXPECT_EQ(o.name, "part");
  EXPECT_EQ(doc.last_created(), std::vector<ObjectId>{o.id});
  const auto& m = std::get<MeshData>(o.data);
  EXPECT_EQ(m.import_source, "/tmp/part.stl");
  EXPECT_EQ(m.source, 0u);
  ASSERT_TRUE(m.surface);
  EXPECT_FALSE(m.volume);
  EXPECT_EQ(m.surface->vertices, Triangle()->vertices);
  EXPECT_EQ(doc.history().UndoDescription(), "Import mesh part");
  const std::string after = doc.ToJson(true).dump();

  ASSERT_TRUE(doc.Undo());
  EXPECT_TRUE(doc.objects().empty());
  EXPECT_FALSE(doc.dirty());
  ASSERT_TRUE(doc.Redo());
  EXPECT_EQ(doc.ToJson(true).dump(), after);  // same id, revision and data
}

TEST(ImportMeshCommand, RepeatedNameGetsACopySuffixAndVolumeKeepsRegions) {
  Document doc;
  doc.Execute(std::make_unique<ImportMeshCommand>("part", "a.stl", Triangle(), nullptr));
  doc.Execute(std::make_unique<ImportMeshCommand>("part", "b.vtu", nullptr, Tet()));
  ASSERT_EQ(doc.objects().size(), 2u);
  EXPECT_EQ(doc.objects()[1].name, "part copy");
  EXPECT_EQ(doc.history().UndoDescription(), "Import mesh part copy");
  const auto& m = std::get<MeshData>(doc.objects()[1].data);
  ASSERT_TRUE(m.volume);
  EXPECT_EQ(m.volume->regions(0), 7);
  EXPECT_EQ(m.import_source, "b.vtu");
}

TEST(ImportMeshCommand, NoMeshOrNonFiniteVerticesThrowAndLeaveTheDocument) {
  Document doc;
  doc.Execute(std::make_unique<ImportMeshCommand>("part", "a.stl", Triangle(), nullptr));
  const std::string before = doc.ToJson(true).dump();
  EXPECT_THROW(doc.Execute(std::make_unique<ImportMeshCommand>("empty", "e.stl", nullptr, nullptr)),
               DocumentError);
  auto bad = std::make_shared<modeling::TriangleMesh>(*Triangle());
  bad->vertices(0, 0) = std::nan("");
  EXPECT_THROW(doc.Execute(std::make_unique<ImportMeshCommand>("nan", "n.stl", bad, nullptr)),
               DocumentError);
  EXPECT_EQ(doc.ToJson(true).dump(), before);
  EXPECT_EQ(doc.history().undo_size(), 1u);
}

}  // namespace
}  // namespace spidarcad::app
