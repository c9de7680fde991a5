// `spidarcad info FILE`: one line per object of a document file (docs/scene-format.md): its kind,
// its name and key counts. A bad file is an InputError (exit status 2) naming the file, line and
// field.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <variant>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "doc/document.h"
#include "doc/input_error.h"

namespace spidarcad::app {
namespace {

int TreeNodeCount(const modeling::ImplicitNode& node) {
  int n = 1;
  for (const auto& c : node.children) n += TreeNodeCount(c);
  return n;
}

std::string Num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

// Seat of a part at pose X_WP that X_WO of the part it names satisfies, or "".
template <class FindPose>
std::string SeatedOn(const Eigen::Isometry3d& X_WP, const std::vector<modeling::SceneSeat>& seats,
                     FindPose&& find_pose) {
  for (const modeling::SceneSeat& seat : seats) {
    Eigen::Isometry3d X_WO;
    if (!find_pose(seat.on, &X_WO)) continue;
    Eigen::Isometry3d X_OS = Eigen::Isometry3d::Identity();
    X_OS.linear() = seat.rotation.toRotationMatrix();
    X_OS.translation() = seat.position;
    const Eigen::Isometry3d X_WS = X_WO * X_OS;
    const double dp = (X_WS.translation() - X_WP.translation()).norm();
    const double angle = Eigen::AngleAxisd(X_WS.linear().transpose() * X_WP.linear()).angle();
    if (dp <= seat.position_tolerance && angle <= seat.angle_tolerance) return seat.on;
  }
  return "";
}

std::string SeatText(bool fixed, bool has_seats, const std::string& on) {
  if (fixed) return "fixed";
  if (!has_seats) return "free";
  return on.empty() ? "not seated" : "seated on '" + on + "'";
}

void RunInfo(const std::string& path) {
  Document doc;
  try {
    doc.Load(path);
  } catch (const modeling::SceneError& e) {
    throw InputError(std::string(e.what()) +
                     (e.pointer().empty()
                          ? ""
                          : " (fix that field; docs/scene-format.md describes every field)"));
  }
  for (const DocObject& o : doc.objects()) {
    std::string kind = ObjectKindName(o.data);
    std::string counts;
    if (const auto* s = std::get_if<SolidData>(&o.data)) {
      counts = "tree_nodes=" + std::to_string(TreeNodeCount(s->root));
    } else if (const auto* m = std::get_if<MeshData>(&o.data)) {
      if (m->volume) {
        kind = "tet_mesh";
        counts = "nodes=" + std::to_string(m->volume->nodes.cols()) +
                 " tets=" + std::to_string(m->volume->tets.cols());
        if (m->surface) counts += " triangles=" + std::to_string(m->surface->triangles.cols());
      } else {
        counts = "nodes=" + std::to_string(m->surface->vertices.cols()) +
                 " triangles=" + std::to_string(m->surface->triangles.cols());
      }
      if (m->source != 0) {
        const DocObject* src = doc.Find(m->source);
        counts += " source='" + (src ? src->name : std::string("?")) + "'" +
                  (doc.IsMeshOutOfDate(o.id) ? " out_of_date" : " up_to_date");
      }
      if (!m->import_source.empty()) counts += " imported_from='" + m->import_source + "'";
    } else if (const auto* s = std::get_if<SculptData>(&o.data)) {
      counts = "nodes=" + std::to_string(s->mesh->vertices.cols()) +
               " triangles=" + std::to_string(s->mesh->triangles.cols());
    } else if (const auto* f = std::get_if<FeModelData>(&o.data)) {
      const DocObject* mesh = doc.Find(f->tet_mesh);
      const auto& md = std::get<MeshData>(mesh->data);
      counts = "tet_mesh='" + mesh->name + "' nodes=" + std::to_string(md.volume->nodes.cols()) +
               " tets=" + std::to_string(md.volume->tets.cols()) + " material=E" +
               Num(f->material.youngs_modulus) + "Pa,nu" + Num(f->material.poisson_ratio) +
               " region_materials=" + std::to_string(f->region_materials.size()) +
               " order=" + std::to_string(f->element_order) +
               " clamps=" + std::to_string(f->fixed_boxes.size()) +
               " loads=" + std::to_string(f->loads.size());
    } else if (const auto* r = std::get_if<RigidPartData>(&o.data)) {
      kind = "part";
      const std::string on =
          SeatedOn(r->X_WP, r->seats, [&](const std::string& name, Eigen::Isometry3d* X) {
            for (const DocObject& other : doc.objects()) {
              const auto* rp = std::get_if<RigidPartData>(&other.data);
              if (rp != nullptr && other.name == name && other.id != o.id) {
                *X = rp->X_WP;
                return true;
              }
            }
            return false;
          });
      counts = "tree_nodes=" + std::to_string(TreeNodeCount(r->root)) + " " +
               SeatText(r->fixed, !r->seats.empty(), on);
    }
    std::printf("%-9s '%s' %s\n", kind.c_str(), o.name.c_str(), counts.c_str());
  }
  // Assembly parts of a version 1 scene ("parts", made of the solids above).
  auto pose = [](const modeling::ScenePart& p) {
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    X.linear() = p.rotation.toRotationMatrix();
    X.translation() = p.position;
    return X;
  };
  for (const modeling::ScenePart& p : doc.parts()) {
    const std::string on =
        SeatedOn(pose(p), p.seats, [&](const std::string& name, Eigen::Isometry3d* X) {
          for (const modeling::ScenePart& other : doc.parts()) {
            if (other.name == name && &other != &p) {
              *X = pose(other);
              return true;
            }
          }
          return false;
        });
    std::printf("%-9s '%s' solid='%s' %s\n", "part", p.name.c_str(), p.solid.c_str(),
                SeatText(p.fixed, !p.seats.empty(), on).c_str());
  }
  // The frame the document was made for (its "device"), last: one line, not an object.
  if (const auto& g = doc.device()) {
    std::printf("%-9s frame=%s,%s,%s pole=%s (m)\n", "device", Num(g->a).c_str(), Num(g->b).c_str(),
                Num(g->c).c_str(), Num(g->d).c_str());
  }
}

}  // namespace

void RegisterInfoCommand(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  CLI::App* cmd =
      app.add_subcommand("info", "List the objects of a document or scene file, one line each");
  cmd->footer(
      "\nEach line: kind (solid, mesh, tet_mesh, sculpt, fe_model, part), 'name', key counts;\n"
      "a last line 'device' gives the frame the document was made for, if it names one.\n"
      "A file that does not load exits with status 2 and names the file, line and field.\n"
      "Example:\n  spidarcad info assets/scenes/workbench.json\n");
  cmd->add_option("file", *path, "Document or scene file (JSON, docs/scene-format.md)")->required();
  cmd->callback([path]() { RunInfo(*path); });
}

}  // namespace spidarcad::app
