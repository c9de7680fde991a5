// `spidarcad import FILE --into DOC`: adds a mesh file (STL, OBJ, PLY surface; VTU or TetGen
// .node/.ele tetrahedra) to a document as a mesh object, through the Document's
// ImportMeshCommand, and writes the document (atomically) to DOC or --out.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "doc/command.h"
#include "doc/document.h"
#include "doc/mesh_import.h"
#include "scene/document_file.h"

namespace spidarcad::app {
namespace {

struct ImportOptions {
  std::string file;
  std::string into;
  std::string name;
  std::string out;
};

void RunImport(const ImportOptions& o) {
  // Everything is read and checked before anything is written.
  MeshFileInfo info;
  const MeshData mesh = ReadMeshFile(o.file, &info);
  std::error_code ec;
  const bool exists = std::filesystem::exists(o.into, ec);
  OpenedDocument opened;
  if (exists) {
    opened = OpenDocumentFile(o.into);
  } else {
    opened.path = o.into;
    opened.version = 2;
    opened.doc = std::make_unique<Document>();
  }
  Document& doc = *opened.doc;
  const std::string name = o.name.empty() ? std::filesystem::path(o.file).stem().string() : o.name;
  if (name.empty()) throw InputError("--name: must not be empty");
  try {
    doc.Execute(std::make_unique<ImportMeshCommand>(name, o.file, mesh.surface, mesh.volume));
  } catch (const std::exception& e) {
    throw InputError(o.file + ": cannot be added to " + o.into + ": " + e.what());
  }
  const DocObject& added = doc.Get(doc.last_created().front());
  const std::string out = o.out.empty() ? o.into : o.out;
  try {
    doc.Save(out);
  } catch (const modeling::SceneError& e) {
    throw InputError(std::string("--out: ") + e.what());
  }
  std::cout << "imported " << o.file << " (" << info.format << ": ";
  if (mesh.volume) {
    std::cout << mesh.volume->nodes.cols() << " nodes, " << mesh.volume->tets.cols()
              << " tetrahedra, " << mesh.surface->triangles.cols() << " boundary triangles";
    if (info.flipped_tets > 0) std::cout << ", " << info.flipped_tets << " reoriented";
  } else {
    std::cout << mesh.surface->vertices.cols() << " vertices, " << mesh.surface->triangles.cols()
              << " triangles";
  }
  std::cout << ") as " << (mesh.volume ? "tet_mesh" : "mesh") << " '" << added.name << "'\n";
  std::cout << "wrote " << out << " (" << doc.objects().size() << " object"
            << (doc.objects().size() == 1 ? "" : "s") << (exists ? "" : ", a new document")
            << ")\n";
}

}  // namespace

void RegisterImportCommand(CLI::App& app) {
  auto options = std::make_shared<ImportOptions>();
  CLI::App* cmd =
      app.add_subcommand("import", "Add a mesh file (STL/OBJ/PLY/VTU/.node) to a document");
  cmd->footer(
      "\nReads FILE by its extension: .stl, .obj, .ply (a triangle surface) or .vtu, .node "
      "(linear\n"
      "tetrahedra; a .node file needs its TetGen .ele beside it, whose first attribute is the\n"
      "region label). Coordinates are metres. Adds it to the document DOC (version 1 or 2; a\n"
      "file that does not exist yet starts an empty document) as a mesh object named NAME\n"
      "(default: the file's name without extension; made unique with \" copy\"), and writes the\n"
      "document to OUT (default: DOC itself), atomically. A bad FILE or DOC exits with status 2\n"
      "naming the file, line or byte, and field; nothing is written then.\n"
      "Example (part.stl: a surface in metres, here made by `spidarcad mesh`):\n"
      "  spidarcad mesh assets/scenes/platform.json --out part.stl\n"
      "  spidarcad import part.stl --into assets/scenes/platform_fe.json --out design.json\n"
      "  spidarcad fem design.json --object part --fix=-1,-1,-1,0.001,1,1 --out part.vtu\n");
  cmd->add_option("file", options->file, "Mesh file: .stl .obj .ply .vtu .node")->required();
  cmd->add_option("--into", options->into, "Document to add it to (JSON)")->required();
  cmd->add_option("--name", options->name, "Name of the new object (default: the file's stem)");
  cmd->add_option("--out", options->out, "Where to write the document (default: --into)");
  cmd->callback([options]() { RunImport(*options); });
}

}  // namespace spidarcad::app
