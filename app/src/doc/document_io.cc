// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "doc/document_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::app {
namespace {

using json = nlohmann::json;
using modeling::SceneError;

static_assert(std::endian::native == std::endian::little,
              "document arrays are little-endian raw bytes");

constexpr const char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

[[noreturn]] void Fail(const std::string& pointer, const std::string& what) {
  throw SceneError("", 0, 0, pointer, what);
}

std::string Hex16(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

// ---- field readers ----

std::string Join(const std::string& p, const std::string& key) { return p + "/" + key; }

const json& Need(const json& obj, const std::string& p, const char* key) {
  if (!obj.contains(key)) Fail(Join(p, key), std::string("missing field '") + key + "'");
  return obj.at(key);
}

void RequireObject(const json& j, const std::string& p) {
  if (!j.is_object()) Fail(p, "expected a JSON object, got " + std::string(j.type_name()));
}

void RejectUnknown(const json& obj, const std::string& p,
                   std::initializer_list<const char*> known) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    if (std::none_of(known.begin(), known.end(), [&](const char* k) { return it.key() == k; })) {
      std::string list;
      for (const char* k : known) list += std::string(list.empty() ? "" : ", ") + k;
      Fail(Join(p, it.key()), "unknown field '" + it.key() + "' (expected one of: " + list + ")");
    }
  }
}

double Number(const json& j, const std::string& p) {
  if (!j.is_number()) Fail(p, "expected a number, got " + std::string(j.type_name()));
  const double v = j.get<double>();
  if (!std::isfinite(v)) Fail(p, "expected a finite number");
  return v;
}

double NonNegative(const json& obj, const std::string& p, const char* key, double fallback) {
  if (!obj.contains(key)) return fallback;
  const double v = Number(obj.at(key), Join(p, key));
  if (v < 0) Fail(Join(p, key), "must be >= 0, got " + std::to_string(v));
  return v;
}

std::string Text(const json& j, const std::string& p) {
  if (!j.is_string()) Fail(p, "expected a string, got " + std::string(j.type_name()));
  return j.get<std::string>();
}

bool Bool(const json& j, const std::string& p) {
  if (!j.is_boolean()) Fail(p, "expected true or false, got " + std::string(j.type_name()));
  return j.get<bool>();
}

Eigen::Vector3d Vec3(const json& j, const std::string& p) {
  if (!j.is_array() || j.size() != 3) Fail(p, "expected an array of 3 numbers");
  return {Number(j[0], p + "/0"), Number(j[1], p + "/1"), Number(j[2], p + "/2")};
}

json VecJson(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

Eigen::Quaterniond Quat(const json& j, const std::string& p) {
  if (!j.is_array() || j.size() != 4) Fail(p, "expected a quaternion [w, x, y, z]");
  Eigen::Quaterniond q(Number(j[0], p + "/0"), Number(j[1], p + "/1"), Number(j[2], p + "/2"),
                       Number(j[3], p + "/3"));
  if (std::abs(q.norm() - 1.0) > 1e-6)
    Fail(p, "the quaternion must have unit norm, got norm " + std::to_string(q.norm()));
  return std::abs(q.norm() - 1.0) > 1e-12 ? q.normalized()
                                          : q;  // unit quaternions kept bit for bit
}

// A rotation matrix written as three rows (exact, unlike a quaternion round trip).
Eigen::Matrix3d Rotation(const json& j, const std::string& p) {
  if (!j.is_array() || j.size() != 3) Fail(p, "expected 3 rows of 3 numbers");
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r) R.row(r) = Vec3(j[r], p + "/" + std::to_string(r)).transpose();
  if (!(R.transpose() * R).isIdentity(1e-9) || R.determinant() < 0)
    Fail(p, "must be a rotation (orthonormal, det +1)");
  return R;
}

json RotationJson(const Eigen::Matrix3d& R) {
  return json::array({VecJson(R.row(0).transpose()), VecJson(R.row(1).transpose()),
                      VecJson(R.row(2).transpose())});
}

json QuatJson(const Eigen::Quaterniond& q) { return json::array({q.w(), q.x(), q.y(), q.z()}); }

Eigen::AlignedBox3d Box(const json& j, const std::string& p,
                        std::initializer_list<const char*> extra = {}) {
  RequireObject(j, p);
  const Eigen::Vector3d lo = Vec3(Need(j, p, "min"), Join(p, "min"));
  const Eigen::Vector3d hi = Vec3(Need(j, p, "max"), Join(p, "max"));
  if ((lo.array() > hi.array()).any())
    Fail(Join(p, "max"), "every coordinate of max must be >= the one of min");
  (void)extra;
  return Eigen::AlignedBox3d(lo, hi);
}

json BoxJson(const Eigen::AlignedBox3d& b) {
  return {{"min", VecJson(b.min())}, {"max", VecJson(b.max())}};
}

fem::Material MaterialFrom(const json& j, const std::string& p) {
  fem::Material m;
  m.youngs_modulus = Number(Need(j, p, "youngs_modulus"), Join(p, "youngs_modulus"));
  m.poisson_ratio = Number(Need(j, p, "poisson_ratio"), Join(p, "poisson_ratio"));
  try {
    m.Validate();
  } catch (const std::invalid_argument& e) {
    Fail(p, e.what());
  }
  return m;
}

json MaterialJson(const fem::Material& m) {
  return {{"youngs_modulus", m.youngs_modulus}, {"poisson_ratio", m.poisson_ratio}};
}

// ---- raw arrays ----

// A column-major rows x cols Eigen matrix as {"dtype", "shape": [cols, rows], "base64"}: the
// file's row-major [cols][rows] array has the same bytes.
template <class Scalar>
json ArrayJson(const Scalar* data, Eigen::Index rows, Eigen::Index cols) {
  const char* dtype = std::is_same_v<Scalar, double> ? "f64" : "i32";
  return {{"dtype", dtype},
          {"shape", rows == 1 ? json::array({cols}) : json::array({cols, rows})},
          {"base64", Base64Encode(data, sizeof(Scalar) * static_cast<std::size_t>(rows * cols))}};
}

// Reads an array written by ArrayJson, or a plain JSON array of `rows`-tuples (hand-written
// files). rows = 1 reads a flat list.
template <class Scalar>
Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic> ArrayFrom(const json& j, const std::string& p,
                                                                Eigen::Index rows) {
  using M = Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>;
  constexpr bool kFloat = std::is_same_v<Scalar, double>;
  const char* want = kFloat ? "f64" : "i32";
  if (j.is_array()) {
    M m(rows, static_cast<Eigen::Index>(j.size()));
    for (std::size_t c = 0; c < j.size(); ++c) {
      const std::string pc = p + "/" + std::to_string(c);
      const json& item = j[c];
      for (Eigen::Index r = 0; r < rows; ++r) {
        const json& v =
            rows == 1
                ? item
                : (item.is_array() && item.size() == static_cast<std::size_t>(rows)
                       ? item[r]
                       : (Fail(pc, "expected an array of " + std::to_string(rows) + " numbers"),
                          item));
        const std::string pv = rows == 1 ? pc : pc + "/" + std::to_string(r);
        if constexpr (kFloat) {
          m(r, c) = Number(v, pv);
        } else {
          if (!v.is_number_integer()) Fail(pv, "expected an integer");
          m(r, c) = v.get<int>();
        }
      }
    }
    return m;
  }
  RequireObject(j, p);
  RejectUnknown(j, p, {"dtype", "shape", "base64"});
  const std::string dtype = Text(Need(j, p, "dtype"), Join(p, "dtype"));
  if (dtype != want)
    Fail(Join(p, "dtype"), "expected \"" + std::string(want) + "\", got \"" + dtype + "\"");
  const json& shape = Need(j, p, "shape");
  const bool shape_ok =
      rows == 1 ? (shape.is_array() && shape.size() == 1 && shape[0].is_number_unsigned())
                : (shape.is_array() && shape.size() == 2 && shape[0].is_number_unsigned() &&
                   shape[1].is_number_unsigned() &&
                   shape[1].get<std::uint64_t>() == static_cast<std::uint64_t>(rows));
  if (!shape_ok) {
    Fail(Join(p, "shape"), rows == 1 ? std::string("expected [count]")
                                     : "expected [count, " + std::to_string(rows) + "]");
  }
  const std::uint64_t count = shape[0].get<std::uint64_t>();
  if (count > (std::uint64_t{1} << 31))
    Fail(Join(p, "shape"), "count " + std::to_string(count) + " is too large");
  std::vector<std::uint8_t> bytes;
  try {
    bytes = Base64Decode(Text(Need(j, p, "base64"), Join(p, "base64")));
  } catch (const std::invalid_argument& e) {
    Fail(Join(p, "base64"), e.what());
  }
  const std::size_t expect =
      sizeof(Scalar) * static_cast<std::size_t>(count) * static_cast<std::size_t>(rows);
  if (bytes.size() != expect) {
    Fail(Join(p, "base64"), "holds " + std::to_string(bytes.size()) +
                                " bytes; shape and dtype need " + std::to_string(expect));
  }
  M m(rows, static_cast<Eigen::Index>(count));
  if (expect > 0) std::memcpy(m.data(), bytes.data(), expect);
  if constexpr (kFloat) {
    if (!m.allFinite()) Fail(Join(p, "base64"), "holds a value that is not finite");
  }
  return m;
}

json SurfaceJson(const modeling::TriangleMesh& m) {
  return {{"vertices", ArrayJson(m.vertices.data(), 3, m.vertices.cols())},
          {"triangles", ArrayJson(m.triangles.data(), 3, m.triangles.cols())}};
}

modeling::TriangleMesh SurfaceFrom(const json& j, const std::string& p) {
  RequireObject(j, p);
  RejectUnknown(j, p, {"vertices", "triangles"});
  modeling::TriangleMesh m;
  m.vertices = ArrayFrom<double>(Need(j, p, "vertices"), Join(p, "vertices"), 3);
  m.triangles = ArrayFrom<int>(Need(j, p, "triangles"), Join(p, "triangles"), 3);
  const auto n = m.vertices.cols();
  if (m.triangles.size() > 0 && (m.triangles.minCoeff() < 0 || m.triangles.maxCoeff() >= n)) {
    Fail(Join(p, "triangles"),
         "a triangle refers to a vertex outside [0, " + std::to_string(n) + ")");
  }
  return m;
}

json VolumeJson(const modeling::TetMesh& m) {
  return {{"nodes", ArrayJson(m.nodes.data(), 3, m.nodes.cols())},
          {"tets", ArrayJson(m.tets.data(), 4, m.tets.cols())},
          {"regions", ArrayJson(m.regions.data(), 1, m.regions.size())}};
}

modeling::TetMesh VolumeFrom(const json& j, const std::string& p) {
  RequireObject(j, p);
  RejectUnknown(j, p, {"nodes", "tets", "regions"});
  modeling::TetMesh m;
  m.nodes = ArrayFrom<double>(Need(j, p, "nodes"), Join(p, "nodes"), 3);
  m.tets = ArrayFrom<int>(Need(j, p, "tets"), Join(p, "tets"), 4);
  if (j.contains("regions")) {
    Eigen::MatrixXi r = ArrayFrom<int>(j.at("regions"), Join(p, "regions"), 1);
    if (r.cols() != m.tets.cols()) {
      Fail(Join(p, "regions"), "has " + std::to_string(r.cols()) + " labels for " +
                                   std::to_string(m.tets.cols()) + " tets");
    }
    m.regions = r.row(0).transpose();
  } else {
    m.regions = Eigen::VectorXi::Zero(m.tets.cols());
  }
  const auto n = m.nodes.cols();
  if (m.tets.size() > 0 && (m.tets.minCoeff() < 0 || m.tets.maxCoeff() >= n)) {
    Fail(Join(p, "tets"), "a tet refers to a node outside [0, " + std::to_string(n) + ")");
  }
  return m;
}

// Surface mesh of a tree at cell size h (the bounds found within ±2 m, padded by a cell).
// The most triangles (modeling::EstimateSurfaceMesh, which errs high) a mesh made at open time
// may have: about seven times the example documents' largest (3e4). A file can ask for a mesh
// that would take minutes to make and TetGen to fill; it is refused instead, before any work.
constexpr double kOpenMaxTriangles = 2e5;

// The surface of `root` (its field at pointer p) at cell h (m, the field at cell_pointer), made
// at open time.
modeling::TriangleMesh MeshTree(const modeling::ImplicitNode& root, double h, const std::string& p,
                                const std::string& cell_pointer) {
  const modeling::CompiledSolid solid = modeling::CompiledSolid::Compile(root, p);
  const Eigen::Vector3d r = Eigen::Vector3d::Constant(2.0);
  const Eigen::AlignedBox3d bounds = modeling::FindBounds(solid, Eigen::AlignedBox3d(-r, r), h);
  if (bounds.isEmpty()) Fail(p, "the solid is empty: nothing to mesh");
  modeling::SurfaceMeshSettings s;
  s.bounds = Eigen::AlignedBox3d(bounds.min() - Eigen::Vector3d::Constant(h),
                                 bounds.max() + Eigen::Vector3d::Constant(h));
  s.cell_size = h;
  try {
    const modeling::SurfaceMeshEstimate estimate = modeling::EstimateSurfaceMesh(solid, s);
    if (estimate.triangles > kOpenMaxTriangles) {
      char over[96];
      std::snprintf(over, sizeof over, "about %.2g triangles, over the %.2g", estimate.triangles,
                    kOpenMaxTriangles);
      Fail(cell_pointer, std::string("meshing at open time would make ") + over +
                             " a document may ask for (" + estimate.Describe() +
                             "; docs/limits.md): raise the cell size, store the mesh in the "
                             "file, or mesh the solid in the window");
    }
    return modeling::MeshSurface(solid, s);
  } catch (const std::invalid_argument& e) {
    Fail(p, e.what());
  }
}

// ---- the parts of a version 1 scene that version 2 keeps in the same form ----

json PartsAndSnapJson(const Document& doc) {
  modeling::Scene scene;
  scene.parts = doc.parts();
  scene.snap = doc.snap();
  return modeling::SceneToJson(scene);
}

// ---- version 2 reader ----

struct Content {
  std::vector<DocObject> objects;
  std::string description;
  std::optional<modeling::SceneSnap> snap;
  std::vector<modeling::ScenePart> parts;
  std::optional<DocView> view;
  std::optional<haptics::SpidarGeometry> device;
};

// "device": {"frame": [a, b, c], "pole": d} (m), checked as SpidarGeometry::Validate does.
haptics::SpidarGeometry DeviceFrom(const json& j, const std::string& p) {
  RequireObject(j, p);
  RejectUnknown(j, p, {"frame", "pole"});
  haptics::SpidarGeometry g;
  const Eigen::Vector3d frame = Vec3(Need(j, p, "frame"), Join(p, "frame"));
  g.a = frame.x();
  g.b = frame.y();
  g.c = frame.z();
  g.d = Number(Need(j, p, "pole"), Join(p, "pole"));
  try {
    g.Validate();
  } catch (const std::invalid_argument& e) {
    Fail(p, std::string(e.what()) + " (frame: half-sides a, b, c in m; pole: half-length d in m)");
  }
  return g;
}

DocView ViewFrom(const json& j, const std::string& p) {
  RequireObject(j, p);
  RejectUnknown(j, p, {"position", "focal_point", "view_up", "view_angle"});
  DocView v;
  v.position = Vec3(Need(j, p, "position"), Join(p, "position"));
  v.focal_point = Vec3(Need(j, p, "focal_point"), Join(p, "focal_point"));
  if (j.contains("view_up")) v.view_up = Vec3(j.at("view_up"), Join(p, "view_up"));
  if (v.view_up.norm() < 1e-12) Fail(Join(p, "view_up"), "must not be zero");
  v.view_up.normalize();
  if (j.contains("view_angle")) v.view_angle = Number(j.at("view_angle"), Join(p, "view_angle"));
  if (!(v.view_angle > 0 && v.view_angle < 180))
    Fail(Join(p, "view_angle"), "must be in (0, 180) degrees");
  return v;
}

int IndexRef(const json& obj, const std::string& p, const char* key, std::size_t count,
             std::size_t self) {
  const json& j = Need(obj, p, key);
  if (!j.is_number_unsigned() || j.get<std::uint64_t>() >= count ||
      j.get<std::uint64_t>() == self) {
    Fail(Join(p, key), "expected the index of another object in /objects (0 to " +
                           std::to_string(count - 1) + ")");
  }
  return j.get<int>();
}

Content ContentFromJson(const json& j) {
  Content c;
  RequireObject(j, "");
  RejectUnknown(j, "",
                {"format", "version", "units", "description", "objects", "parts", "snap", "view",
                 "device", "recovered_from"});
  if (j.contains("units") && Text(j.at("units"), "/units") != "m")
    Fail("/units", "only \"m\" is supported");
  if (j.contains("description")) c.description = Text(j.at("description"), "/description");
  if (j.contains("view")) c.view = ViewFrom(j.at("view"), "/view");
  if (j.contains("device")) c.device = DeviceFrom(j.at("device"), "/device");
  if (j.contains("recovered_from")) Text(j.at("recovered_from"), "/recovered_from");
  const json& objects = Need(j, "", "objects");
  if (!objects.is_array()) Fail("/objects", "expected an array of objects");
  const std::size_t n = objects.size();
  // References between objects, resolved to ids once every object has one.
  std::vector<int> mesh_source(n, -1), fe_mesh(n, -1);
  std::vector<bool> up_to_date(n, false);
  std::vector<std::string> generate(n);
  json solids = json::array();  // for checking parts and snap with the version 1 reader
  std::vector<std::size_t> solid_at;
  for (std::size_t i = 0; i < n; ++i) {
    const std::string p = "/objects/" + std::to_string(i);
    const json& o = objects[i];
    RequireObject(o, p);
    DocObject d;
    d.name = Text(Need(o, p, "name"), p + "/name");
    if (d.name.empty()) Fail(p + "/name", "the name must not be empty");
    const std::string kind = Text(Need(o, p, "kind"), p + "/kind");
    auto tree = [&](const json& node, const std::string& tp) {
      modeling::ImplicitNode root = modeling::NodeFromJson(node, tp);
      try {
        modeling::ValidateTree(root, tp);
      } catch (const modeling::ModelError& e) {
        Fail(e.path() + "/" + e.field(), e.what());
      }
      return root;
    };
    if (kind == "solid") {
      RejectUnknown(o, p, {"kind", "name", "root"});
      d.data = SolidData{tree(Need(o, p, "root"), p + "/root")};
      solids.push_back({{"name", d.name}, {"root", o.at("root")}});
      solid_at.push_back(i);
    } else if (kind == "mesh") {
      RejectUnknown(o, p,
                    {"kind", "name", "source", "up_to_date", "settings", "import_source", "surface",
                     "volume", "generate"});
      MeshData m;
      if (o.contains("source") && !o.at("source").is_null())
        mesh_source[i] = IndexRef(o, p, "source", n, i);
      if (o.contains("up_to_date")) up_to_date[i] = Bool(o.at("up_to_date"), p + "/up_to_date");
      if (o.contains("import_source"))
        m.import_source = Text(o.at("import_source"), p + "/import_source");
      if (o.contains("settings")) {
        const json& s = o.at("settings");
        const std::string sp = p + "/settings";
        RequireObject(s, sp);
        RejectUnknown(s, sp,
                      {"cell_size", "max_tet_volume", "max_radius_edge", "mesher", "sharp_edges",
                       "surface_mesher", "flat_cells", "slab_planes", "slab_strips"});
        m.settings.cell_size = NonNegative(s, sp, "cell_size", 0.0);
        m.settings.max_tet_volume = NonNegative(s, sp, "max_tet_volume", 0.0);
        m.settings.max_radius_edge = NonNegative(s, sp, "max_radius_edge", 0.0);
        if (m.settings.max_radius_edge != 0.0 && m.settings.max_radius_edge < 1.0) {
          Fail(sp + "/max_radius_edge", "must be 0 (default) or >= 1");
        }
        if (s.contains("mesher")) {
          m.settings.mesher = Text(s.at("mesher"), sp + "/mesher");
          if (m.settings.mesher != "tetgen" && m.settings.mesher != "cgal")
            Fail(sp + "/mesher", "expected \"tetgen\" or \"cgal\"");
        }
        if (s.contains("sharp_edges"))
          m.settings.sharp_edges = Bool(s.at("sharp_edges"), sp + "/sharp_edges");
        if (s.contains("surface_mesher")) {
          m.settings.surface_mesher = Text(s.at("surface_mesher"), sp + "/surface_mesher");
          if (m.settings.surface_mesher != "lattice")
            Fail(sp + "/surface_mesher", "expected \"lattice\" (or no key: marching tetrahedra)");
          if (m.settings.mesher == "cgal")
            Fail(sp + "/surface_mesher", "CGAL meshes from the solid and uses no surface");
        }
        if (s.contains("flat_cells")) {
          const std::string fp = sp + "/flat_cells";
          m.settings.flat_cells = Number(s.at("flat_cells"), fp);
          if (!(m.settings.flat_cells >= 0.0 && m.settings.flat_cells <= 1.0))
            Fail(fp, "expected a number of cells in [0, 1] (0: flat faces not coarsened)");
          if (m.settings.flat_cells > 0.0 &&
              (m.settings.mesher == "cgal" || !m.settings.surface_mesher.empty()))
            Fail(fp,
                 "flat faces are coarsened on the marching-tetrahedra surface TetGen uses: drop "
                 "it, or settings/mesher \"cgal\" and settings/surface_mesher");
        }
        if (s.contains("slab_planes")) {
          const json& planes = s.at("slab_planes");
          const std::string pp = sp + "/slab_planes";
          if (!planes.is_array()) Fail(pp, "expected an array of plane positions x (m)");
          for (std::size_t k = 0; k < planes.size(); ++k) {
            const double x = Number(planes[k], pp + "/" + std::to_string(k));
            if (k > 0 && !(x > m.settings.slab_planes.back()))
              Fail(pp + "/" + std::to_string(k), "the planes must increase");
            m.settings.slab_planes.push_back(x);
          }
        }
        if (s.contains("slab_strips")) {
          const json& strips = s.at("slab_strips");
          const std::string tp = sp + "/slab_strips";
          RequireObject(strips, tp);
          RejectUnknown(strips, tp, {"axis", "planes"});
          const std::string axis =
              strips.contains("axis") ? Text(strips.at("axis"), tp + "/axis") : std::string();
          if (axis != "y" && axis != "z") Fail(tp + "/axis", "expected \"y\" or \"z\"");
          m.settings.slab_strip_axis = axis == "y" ? 1 : 2;
          const std::string pp = tp + "/planes";
          if (!strips.contains("planes") || !strips.at("planes").is_array())
            Fail(pp, "expected an array of each slab's strip planes (m)");
          const json& planes = strips.at("planes");
          if (planes.size() != m.settings.slab_planes.size() + 1)
            Fail(pp, "expected one list per slab (" +
                         std::to_string(m.settings.slab_planes.size() + 1) +
                         ", from slab_planes), got " + std::to_string(planes.size()));
          for (std::size_t k = 0; k < planes.size(); ++k) {
            const std::string kp = pp + "/" + std::to_string(k);
            if (!planes[k].is_array()) Fail(kp, "expected an array of plane positions (m)");
            std::vector<double> list;
            for (std::size_t j = 0; j < planes[k].size(); ++j) {
              const double c = Number(planes[k][j], kp + "/" + std::to_string(j));
              if (j > 0 && !(c > list.back()))
                Fail(kp + "/" + std::to_string(j), "the planes must increase");
              list.push_back(c);
            }
            m.settings.slab_strips.push_back(std::move(list));
          }
        }
      }
      if (o.contains("surface"))
        m.surface =
            std::make_shared<modeling::TriangleMesh>(SurfaceFrom(o.at("surface"), p + "/surface"));
      if (o.contains("volume"))
        m.volume = std::make_shared<modeling::TetMesh>(VolumeFrom(o.at("volume"), p + "/volume"));
      if (o.contains("generate")) {
        generate[i] = Text(o.at("generate"), p + "/generate");
        if (generate[i] != "surface" && generate[i] != "volume")
          Fail(p + "/generate", "expected \"surface\" or \"volume\"");
        if (m.surface || m.volume)
          Fail(p + "/generate", "a mesh is either stored (surface, volume) or generated, not both");
        if (mesh_source[i] < 0)
          Fail(p + "/source", "a generated mesh needs the index of its source solid");
        if (!(m.settings.cell_size > 0))
          Fail(p + "/settings/cell_size", "a generated mesh needs a cell size > 0");
        if (m.settings.mesher == "cgal" || m.settings.sharp_edges ||
            !m.settings.surface_mesher.empty() || m.settings.flat_cells != 0.0)
          Fail(p + "/generate",
               "\"generate\" meshes with TetGen on the plain grid surface: drop settings/mesher "
               "\"cgal\", settings/sharp_edges, settings/surface_mesher and "
               "settings/flat_cells, or store the mesh (surface, volume)");
        up_to_date[i] = true;
      } else if (!m.surface && !m.volume) {
        Fail(p, "a mesh object needs \"surface\", \"volume\" or \"generate\"");
      }
      d.data = std::move(m);
    } else if (kind == "sculpt") {
      RejectUnknown(o, p, {"kind", "name", "mesh", "generate_from"});
      SculptData s;
      if (o.contains("mesh")) {
        s.mesh = std::make_shared<SculptMesh>(SurfaceFrom(o.at("mesh"), p + "/mesh"));
      } else {
        const json& g = Need(o, p, "generate_from");
        const std::string gp = p + "/generate_from";
        RequireObject(g, gp);
        RejectUnknown(g, gp, {"root", "cell_size"});
        const double h = Number(Need(g, gp, "cell_size"), gp + "/cell_size");
        if (!(h >= 1e-4)) Fail(gp + "/cell_size", "must be >= 1e-4 m");
        s.mesh = std::make_shared<SculptMesh>(
            MeshTree(tree(Need(g, gp, "root"), gp + "/root"), h, gp + "/root", gp + "/cell_size"));
      }
      d.data = std::move(s);
    } else if (kind == "fe_model") {
      RejectUnknown(o, p,
                    {"kind", "name", "tet_mesh", "material", "region_materials", "fixed_boxes",
                     "loads", "element_order", "precompute_key"});
      FeModelData f;
      fe_mesh[i] = IndexRef(o, p, "tet_mesh", n, i);
      f.material = MaterialFrom(Need(o, p, "material"), p + "/material");
      if (o.contains("region_materials")) {
        const json& rm = o.at("region_materials");
        if (!rm.is_array()) Fail(p + "/region_materials", "expected an array");
        for (std::size_t k = 0; k < rm.size(); ++k) {
          const std::string rp = p + "/region_materials/" + std::to_string(k);
          RequireObject(rm[k], rp);
          RejectUnknown(rm[k], rp, {"region", "youngs_modulus", "poisson_ratio"});
          const json& r = Need(rm[k], rp, "region");
          if (!r.is_number_integer()) Fail(rp + "/region", "expected an integer region label");
          for (const RegionMaterial& prev : f.region_materials) {
            if (prev.region == r.get<int>())
              Fail(rp + "/region", "region " + std::to_string(prev.region) + " is listed twice");
          }
          f.region_materials.push_back({r.get<int>(), MaterialFrom(rm[k], rp)});
        }
      }
      if (o.contains("fixed_boxes")) {
        const json& b = o.at("fixed_boxes");
        if (!b.is_array()) Fail(p + "/fixed_boxes", "expected an array of boxes");
        for (std::size_t k = 0; k < b.size(); ++k) {
          const std::string bp = p + "/fixed_boxes/" + std::to_string(k);
          RequireObject(b[k], bp);
          RejectUnknown(b[k], bp, {"min", "max"});
          f.fixed_boxes.push_back(Box(b[k], bp));
        }
      }
      if (o.contains("loads")) {
        const json& l = o.at("loads");
        if (!l.is_array()) Fail(p + "/loads", "expected an array of loads");
        for (std::size_t k = 0; k < l.size(); ++k) {
          const std::string lp = p + "/loads/" + std::to_string(k);
          RequireObject(l[k], lp);
          RejectUnknown(l[k], lp, {"min", "max", "force"});
          f.loads.push_back({Box(l[k], lp), Vec3(Need(l[k], lp, "force"), lp + "/force")});
        }
      }
      if (o.contains("element_order")) {
        const json& e = o.at("element_order");
        if (!e.is_number_integer() || (e.get<int>() != 1 && e.get<int>() != 2))
          Fail(p + "/element_order", "expected 1 or 2");
        f.element_order = e.get<int>();
      }
      if (o.contains("precompute_key")) {
        const std::string key = Text(o.at("precompute_key"), p + "/precompute_key");
        if (key.size() != 16 || key.find_first_not_of("0123456789abcdef") != std::string::npos) {
          Fail(p + "/precompute_key", "expected 16 lower-case hex digits, got \"" + key + "\"");
        }
        f.precompute_key = std::stoull(key, nullptr, 16);
      }
      d.data = std::move(f);
    } else if (kind == "rigid_part") {
      RejectUnknown(o, p,
                    {"kind", "name", "root", "position", "quaternion", "rotation", "axis", "angle",
                     "fixed", "seats"});
      RigidPartData r;
      r.root = tree(Need(o, p, "root"), p + "/root");
      r.X_WP.translation() = Vec3(Need(o, p, "position"), p + "/position");
      if (o.contains("quaternion"))
        r.X_WP.linear() = Quat(o.at("quaternion"), p + "/quaternion").toRotationMatrix();
      if (o.contains("rotation")) r.X_WP.linear() = Rotation(o.at("rotation"), p + "/rotation");
      if (o.contains("axis") || o.contains("angle")) {
        const Eigen::Vector3d axis = Vec3(Need(o, p, "axis"), p + "/axis");
        if (axis.norm() < 1e-12) Fail(p + "/axis", "must not be zero");
        r.X_WP.linear() =
            Eigen::AngleAxisd(Number(Need(o, p, "angle"), p + "/angle"), axis.normalized())
                .toRotationMatrix();
      }
      if (o.contains("fixed")) r.fixed = Bool(o.at("fixed"), p + "/fixed");
      if (o.contains("seats")) {
        const json& s = o.at("seats");
        if (!s.is_array()) Fail(p + "/seats", "expected an array of seats");
        for (std::size_t k = 0; k < s.size(); ++k) {
          const std::string sp = p + "/seats/" + std::to_string(k);
          RequireObject(s[k], sp);
          RejectUnknown(s[k], sp,
                        {"on", "position", "quaternion", "position_tolerance", "angle_tolerance"});
          modeling::SceneSeat seat;
          seat.on = Text(Need(s[k], sp, "on"), sp + "/on");
          seat.position = Vec3(Need(s[k], sp, "position"), sp + "/position");
          if (s[k].contains("quaternion"))
            seat.rotation = Quat(s[k].at("quaternion"), sp + "/quaternion");
          seat.position_tolerance =
              NonNegative(s[k], sp, "position_tolerance", seat.position_tolerance);
          seat.angle_tolerance = NonNegative(s[k], sp, "angle_tolerance", seat.angle_tolerance);
          r.seats.push_back(seat);
        }
      }
      d.data = std::move(r);
    } else {
      Fail(p + "/kind",
           "unknown kind \"" + kind + "\" (expected solid, mesh, sculpt, fe_model or rigid_part)");
    }
    c.objects.push_back(std::move(d));
  }
  // Seats name another rigid part of the document.
  for (std::size_t i = 0; i < n; ++i) {
    if (const auto* r = std::get_if<RigidPartData>(&c.objects[i].data)) {
      for (std::size_t k = 0; k < r->seats.size(); ++k) {
        const bool found = std::any_of(c.objects.begin(), c.objects.end(), [&](const DocObject& o) {
          return &o != &c.objects[i] && std::holds_alternative<RigidPartData>(o.data) &&
                 o.name == r->seats[k].on;
        });
        if (!found) {
          Fail("/objects/" + std::to_string(i) + "/seats/" + std::to_string(k) + "/on",
               "no other rigid part is named '" + r->seats[k].on + "'");
        }
      }
    }
  }
  // Generated meshes: mesh the source solid now.
  for (std::size_t i = 0; i < n; ++i) {
    if (generate[i].empty()) continue;
    const std::string p = "/objects/" + std::to_string(i);
    const auto* src = std::get_if<SolidData>(&c.objects[mesh_source[i]].data);
    if (src == nullptr) Fail(p + "/source", "a generated mesh's source must be a solid");
    auto& m = std::get<MeshData>(c.objects[i].data);
    auto surface =
        MeshTree(src->root, m.settings.cell_size,
                 "/objects/" + std::to_string(mesh_source[i]) + "/root", p + "/settings/cell_size");
    if (generate[i] == "volume") {
      modeling::TetMeshSettings ts;
      if (m.settings.max_radius_edge > 0) ts.max_radius_edge = m.settings.max_radius_edge;
      ts.max_volume = m.settings.max_tet_volume;
      try {
        m.volume =
            std::make_shared<modeling::TetMesh>(modeling::TetrahedralizeSurface(surface, ts));
      } catch (const std::exception& e) {
        Fail(p + "/generate", std::string("tetrahedral meshing failed: ") + e.what());
      }
    }
    m.surface = std::make_shared<modeling::TriangleMesh>(std::move(surface));
  }
  // Parts and snap: the version 1 reader checks them against the solids.
  json v1 = {
      {"format", modeling::kSceneFormat}, {"version", 1}, {"units", "m"}, {"solids", solids}};
  if (j.contains("parts")) v1["parts"] = j.at("parts");
  if (j.contains("snap")) v1["snap"] = j.at("snap");
  try {
    modeling::Scene scene = modeling::SceneFromJson(v1, "");
    c.parts = std::move(scene.parts);
    c.snap = scene.snap;
  } catch (const SceneError& e) {
    std::string pointer = e.pointer();
    if (pointer.rfind("/solids/", 0) == 0) {  // map back to the object index
      const std::size_t end = pointer.find('/', 8);
      const std::size_t k = std::stoul(pointer.substr(8, end - 8));
      pointer = "/objects/" + std::to_string(solid_at.at(k)) +
                (end == std::string::npos ? "" : pointer.substr(end));
    }
    Fail(pointer, e.message());
  }
  // References as indices: stored in the data fields for AdoptContent (see document.h).
  for (std::size_t i = 0; i < n; ++i) {
    if (auto* m = std::get_if<MeshData>(&c.objects[i].data)) {
      m->source = mesh_source[i] >= 0 ? static_cast<ObjectId>(mesh_source[i]) + 1 : 0;
      m->source_revision = up_to_date[i] ? 1 : 0;  // AdoptContent: 1 = up to date
    }
    if (auto* f = std::get_if<FeModelData>(&c.objects[i].data))
      f->tet_mesh = static_cast<ObjectId>(fe_mesh[i]) + 1;
  }
  return c;
}

json ObjectJson(const Document& doc, const DocObject& o) {
  json j = {{"kind", ObjectKindName(o.data)}, {"name", o.name}};
  auto index_of = [&](ObjectId id) { return doc.IndexOf(id); };
  if (const auto* s = std::get_if<SolidData>(&o.data)) {
    j["root"] = modeling::NodeToJson(s->root);
  } else if (const auto* m = std::get_if<MeshData>(&o.data)) {
    const int src = m->source != 0 ? index_of(m->source) : -1;
    j["source"] = src >= 0 ? json(src) : json(nullptr);
    j["up_to_date"] = src >= 0 && !doc.IsMeshOutOfDate(o.id);
    j["settings"] = {{"cell_size", m->settings.cell_size},
                     {"max_tet_volume", m->settings.max_tet_volume},
                     {"max_radius_edge", m->settings.max_radius_edge}};
    if (!m->settings.mesher.empty()) j["settings"]["mesher"] = m->settings.mesher;
    if (m->settings.sharp_edges) j["settings"]["sharp_edges"] = true;
    if (!m->settings.surface_mesher.empty())
      j["settings"]["surface_mesher"] = m->settings.surface_mesher;
    if (m->settings.flat_cells != 0.0) j["settings"]["flat_cells"] = m->settings.flat_cells;
    if (!m->settings.slab_planes.empty()) j["settings"]["slab_planes"] = m->settings.slab_planes;
    if (!m->settings.slab_strips.empty())
      j["settings"]["slab_strips"] = {{"axis", m->settings.slab_strip_axis == 1 ? "y" : "z"},
                                      {"planes", m->settings.slab_strips}};
    if (!m->import_source.empty()) j["import_source"] = m->import_source;
    if (m->surface) j["surface"] = SurfaceJson(*m->surface);
    if (m->volume) j["volume"] = VolumeJson(*m->volume);
  } else if (const auto* f = std::get_if<FeModelData>(&o.data)) {
    j["tet_mesh"] = index_of(f->tet_mesh);
    j["material"] = MaterialJson(f->material);
    json rm = json::array();
    for (const RegionMaterial& r : f->region_materials) {
      json e = MaterialJson(r.material);
      e["region"] = r.region;
      rm.push_back(e);
    }
    j["region_materials"] = rm;
    json boxes = json::array();
    for (const auto& b : f->fixed_boxes) boxes.push_back(BoxJson(b));
    j["fixed_boxes"] = boxes;
    json loads = json::array();
    for (const FeLoad& l : f->loads) {
      json e = BoxJson(l.box);
      e["force"] = VecJson(l.force);
      loads.push_back(e);
    }
    j["loads"] = loads;
    j["element_order"] = f->element_order;
    if (f->precompute_key != 0) j["precompute_key"] = Hex16(f->precompute_key);
  } else if (const auto* s = std::get_if<SculptData>(&o.data)) {
    j["mesh"] = SurfaceJson(*s->mesh);
  } else if (const auto* r = std::get_if<RigidPartData>(&o.data)) {
    j["root"] = modeling::NodeToJson(r->root);
    j["position"] = VecJson(r->X_WP.translation());
    j["rotation"] = RotationJson(r->X_WP.linear());
    j["fixed"] = r->fixed;
    json seats = json::array();
    for (const modeling::SceneSeat& s : r->seats) {
      seats.push_back({{"on", s.on},
                       {"position", VecJson(s.position)},
                       {"quaternion", QuatJson(s.rotation)},
                       {"position_tolerance", s.position_tolerance},
                       {"angle_tolerance", s.angle_tolerance}});
    }
    j["seats"] = seats;
  }
  return j;
}

}  // namespace

std::string Base64Encode(const void* data, std::size_t size) {
  const auto* b = static_cast<const std::uint8_t*>(data);
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 3 <= size; i += 3) {
    const std::uint32_t v = (b[i] << 16) | (b[i + 1] << 8) | b[i + 2];
    out += kBase64[v >> 18];
    out += kBase64[(v >> 12) & 63];
    out += kBase64[(v >> 6) & 63];
    out += kBase64[v & 63];
  }
  if (i + 1 == size) {
    const std::uint32_t v = b[i] << 16;
    out += kBase64[v >> 18];
    out += kBase64[(v >> 12) & 63];
    out += "==";
  } else if (i + 2 == size) {
    const std::uint32_t v = (b[i] << 16) | (b[i + 1] << 8);
    out += kBase64[v >> 18];
    out += kBase64[(v >> 12) & 63];
    out += kBase64[(v >> 6) & 63];
    out += '=';
  }
  return out;
}

std::vector<std::uint8_t> Base64Decode(const std::string& text) {
  static const auto table = [] {
    std::array<int, 256> t;
    t.fill(-1);
    for (int k = 0; k < 64; ++k) t[static_cast<unsigned char>(kBase64[k])] = k;
    return t;
  }();
  if (text.size() % 4 != 0) {
    throw std::invalid_argument("base64 text length " + std::to_string(text.size()) +
                                " is not a multiple of 4");
  }
  std::vector<std::uint8_t> out;
  out.reserve(text.size() / 4 * 3);
  for (std::size_t i = 0; i < text.size(); i += 4) {
    int v[4];
    int pad = 0;
    for (int k = 0; k < 4; ++k) {
      const char ch = text[i + k];
      if (ch == '=' && i + 4 == text.size() && k >= 2) {
        v[k] = 0;
        ++pad;
        continue;
      }
      v[k] = table[static_cast<unsigned char>(ch)];
      if (v[k] < 0 || pad > 0)
        throw std::invalid_argument("bad base64 character at offset " + std::to_string(i + k));
    }
    const std::uint32_t w = (v[0] << 18) | (v[1] << 12) | (v[2] << 6) | v[3];
    out.push_back(static_cast<std::uint8_t>(w >> 16));
    if (pad < 2) out.push_back(static_cast<std::uint8_t>((w >> 8) & 255));
    if (pad < 1) out.push_back(static_cast<std::uint8_t>(w & 255));
  }
  return out;
}

bool FitsSceneVersion1(const Document& doc) {
  if (doc.view() || doc.device()) return false;
  return std::all_of(doc.objects().begin(), doc.objects().end(),
                     [](const DocObject& o) { return std::holds_alternative<SolidData>(o.data); });
}

json DocumentToFileJson(const Document& doc, const DocumentWriteOptions& options) {
  if (!options.force_version2 && FitsSceneVersion1(doc))
    return modeling::SceneToJson(doc.ToScene());
  json j;
  j["format"] = modeling::kSceneFormat;
  j["version"] = kDocumentVersion;
  j["units"] = "m";
  if (!doc.description().empty()) j["description"] = doc.description();
  if (options.mark_recovery || !options.recovered_from.empty())
    j["recovered_from"] = options.recovered_from;
  if (const auto& v = doc.view()) {
    j["view"] = {{"position", VecJson(v->position)},
                 {"focal_point", VecJson(v->focal_point)},
                 {"view_up", VecJson(v->view_up)},
                 {"view_angle", v->view_angle}};
  }
  if (const auto& g = doc.device()) j["device"] = {{"frame", {g->a, g->b, g->c}}, {"pole", g->d}};
  json objects = json::array();
  for (const DocObject& o : doc.objects()) objects.push_back(ObjectJson(doc, o));
  j["objects"] = objects;
  const json rest = PartsAndSnapJson(doc);
  if (rest.contains("parts")) j["parts"] = rest.at("parts");
  if (rest.contains("snap")) j["snap"] = rest.at("snap");
  return j;
}

void WriteDocumentFile(const Document& doc, const std::string& path,
                       const DocumentWriteOptions& options) {
  namespace fs = std::filesystem;
  const json j = DocumentToFileJson(doc, options);
  const bool v1 = j.at("version") == 1;
  const std::string text = j.dump(v1 ? 2 : 1) + "\n";
  const fs::path target(path);
  std::mt19937_64 rng(std::random_device{}());
  const fs::path tmp =
      target.parent_path() / (target.filename().string() + ".tmp" + Hex16(rng()).substr(0, 8));
  auto fail = [&](const std::string& what) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw SceneError(path, 0, 0, "", what);
  };
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0)
    throw SceneError(path, 0, 0, "",
                     "cannot write the file: " + std::string(std::strerror(errno)) +
                         " (check that the folder exists and is writable)");
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t w = ::write(fd, text.data() + done, text.size() - done);
    if (w < 0) {
      if (errno == EINTR) continue;
      const std::string why = std::strerror(errno);
      ::close(fd);
      fail("cannot write the file: " + why);
    }
    done += static_cast<std::size_t>(w);
  }
  if (::fsync(fd) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    fail("cannot flush the file to disk: " + why);
  }
  if (::close(fd) != 0) fail("cannot close the file: " + std::string(std::strerror(errno)));
  if (::rename(tmp.c_str(), target.c_str()) != 0)
    fail("cannot replace the file: " + std::string(std::strerror(errno)));
}

int ParseDocumentText(const std::string& text, const std::string& source, Document* doc) {
  // Syntax, nesting and number errors with line, column and field; no recursion.
  const json j = modeling::ParseJsonText(text, source);
  const bool v2 = j.is_object() && j.contains("version") && j.at("version").is_number_integer() &&
                  j.at("version").get<int>() == 2;
  if (j.is_object() && j.contains("version") && j.at("version").is_number_integer() &&
      j.at("version").get<int>() > kDocumentVersion) {
    int line = 0, column = 0;
    modeling::LocateJsonPointer(text, "/version", &line, &column);
    throw SceneError(source, line, column, "/version",
                     "version " + std::to_string(j.at("version").get<int>()) +
                         " was written by a newer spidarcad; this one reads versions 1 and 2");
  }
  if (!v2) {
    doc->LoadScene(modeling::ParseScene(j, text, source), source);  // j: not parsed again
    return 1;
  }
  try {
    if (!j.contains("format") || !j.at("format").is_string() ||
        j.at("format").get<std::string>() != modeling::kSceneFormat) {
      Fail("/format", std::string("expected \"") + modeling::kSceneFormat + "\"");
    }
    Content c = ContentFromJson(j);
    doc->AdoptContent(std::move(c.objects), std::move(c.description), c.snap, std::move(c.parts),
                      c.view, source);
    doc->set_device(c.device);
  } catch (const SceneError& e) {
    if (e.line() > 0 || e.pointer().empty()) throw;
    int line = 0, column = 0;
    modeling::LocateJsonPointer(text, e.pointer(), &line, &column);
    throw SceneError(source, line, column, e.pointer(), e.message());
  }
  return 2;
}

int ReadDocumentFile(const std::string& path, Document* doc) {
  return ParseDocumentText(modeling::ReadBoundedFile(path, kMaxDocumentFileBytes, "document file"),
                           path, doc);
}

bool ReadRecoveredFrom(const std::string& path, std::string* original) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  try {
    const json j = json::parse(in);
    if (!j.is_object() || !j.contains("recovered_from") || !j.at("recovered_from").is_string())
      return false;
    *original = j.at("recovered_from").get<std::string>();
    return true;
  } catch (const json::exception&) {
    return false;
  }
}

}  // namespace spidarcad::app
