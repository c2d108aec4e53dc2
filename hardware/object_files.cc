// Object meshes and scanned point clouds: PLY (ASCII or binary little endian), OBJ, STL, PTS, XYZ.
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <sstream>
#include <vector>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/hardware/geometry.h"

namespace fs = std::filesystem;

namespace sonicboom::hardware {
namespace {

struct Builder {
  std::string path;
  double scale;
  std::vector<float> v;  // x y z ...
  std::vector<int> f;    // a b c ...
  void Vertex(double x, double y, double z, const std::string& where) {
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
      throw IoError(fmt::format("{}: a coordinate is not finite", where));
    }
    v.insert(v.end(), {float(x * scale), float(y * scale), float(z * scale)});
  }
  // a polygon as a fan of triangles
  void Polygon(const std::vector<long>& idx, const std::string& where) {
    const long n = static_cast<long>(v.size() / 3);
    for (long i : idx) {
      if (i < 0 || i >= n)
        throw IoError(fmt::format("{}: vertex index {} is out of range (0-{})", where, i, n - 1));
    }
    for (size_t k = 2; k < idx.size(); ++k)
      f.insert(f.end(), {int(idx[0]), int(idx[k - 1]), int(idx[k])});
  }
  ObjectGeometry Done() const {
    if (v.empty()) throw IoError(fmt::format("{}: no vertices", path));
    ObjectGeometry g;
    g.vertices = Eigen::Map<const Eigen::Matrix3Xf>(v.data(), 3, v.size() / 3);
    g.triangles = Eigen::Map<const Eigen::Matrix3Xi>(f.data(), 3, f.size() / 3);
    return g;
  }
};

std::string ReadAll(const std::string& path) {
  RequireReadableFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fmt::format("{}: cannot open object file", path));
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Whitespace text: x y z [more] per line; a .pts file's first line (its count) is skipped.
ObjectGeometry ReadCloudText(Builder b, const std::string& text, bool skip_first) {
  std::istringstream in(text);
  std::string line;
  for (int no = 1; std::getline(in, line); ++no) {
    if ((skip_first && no == 1) || line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream cells(line);
    std::string x, y, z;  // strtod's syntax, so that "nan" reads and is then refused
    if (!(cells >> x >> y >> z)) throw IoError(fmt::format("{}:{}: expected x y z", b.path, no));
    b.Vertex(std::stod(x), std::stod(y), std::stod(z), fmt::format("{}:{}", b.path, no));
  }
  return b.Done();
}

ObjectGeometry ReadObj(Builder b, const std::string& text) {
  std::istringstream in(text);
  std::string line;
  for (int no = 1; std::getline(in, line); ++no) {
    std::istringstream cells(line);
    std::string tag;
    cells >> tag;
    const std::string where = fmt::format("{}:{}", b.path, no);
    if (tag == "v") {
      double x, y, z;
      if (!(cells >> x >> y >> z)) throw IoError(where + ": expected v x y z");
      b.Vertex(x, y, z, where);
    } else if (tag == "f") {
      std::vector<long> idx;
      for (std::string item; cells >> item;) {
        const long i = std::stol(item.substr(0, item.find('/')));  // "a/b/c": the vertex
        idx.push_back(i < 0 ? long(b.v.size() / 3) + i : i - 1);   // 1-based, or from the end
      }
      if (idx.size() < 3) throw IoError(where + ": a face needs three vertices");
      b.Polygon(idx, where);
    }
  }
  return b.Done();
}

ObjectGeometry ReadStl(Builder b, const std::string& bytes) {
  // binary: 80-byte header, count, 50 bytes per triangle (normal, 3 vertices, attribute)
  if (bytes.size() >= 84) {
    uint32_t n;
    std::memcpy(&n, bytes.data() + 80, 4);
    if (bytes.size() == 84 + 50ull * n) {
      for (uint32_t t = 0; t < n; ++t) {
        float xyz[9];
        std::memcpy(xyz, bytes.data() + 84 + 50ull * t + 12, sizeof(xyz));
        for (int k = 0; k < 3; ++k) b.Vertex(xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2], b.path);
        const long first = long(b.v.size() / 3) - 3;
        b.Polygon({first, first + 1, first + 2}, b.path);
      }
      return b.Done();
    }
  }
  if (bytes.rfind("solid", 0) != 0)
    throw IoError(fmt::format("{}: neither binary nor ASCII STL", b.path));
  std::istringstream in(bytes);
  std::string line;
  std::vector<long> facet;
  for (int no = 1; std::getline(in, line); ++no) {
    std::istringstream cells(line);
    std::string tag;
    cells >> tag;
    if (tag == "vertex") {
      double x, y, z;
      if (!(cells >> x >> y >> z))
        throw IoError(fmt::format("{}:{}: expected vertex x y z", b.path, no));
      b.Vertex(x, y, z, fmt::format("{}:{}", b.path, no));
      facet.push_back(long(b.v.size() / 3) - 1);
    } else if (tag == "endfacet") {
      b.Polygon(facet, fmt::format("{}:{}", b.path, no));
      facet.clear();
    }
  }
  return b.Done();
}

// PLY: vertex x y z (any scalar type, other properties skipped), optional face lists.
ObjectGeometry ReadPly(Builder b, const std::string& bytes) {
  const size_t end = bytes.find("end_header");
  if (bytes.rfind("ply", 0) != 0 || end == std::string::npos)
    throw IoError(fmt::format("{}: not a PLY file", b.path));
  std::istringstream header(bytes.substr(0, end));
  std::string line, format, element;
  struct Property {
    std::string name, type, count_type;
  };
  std::vector<Property> vertex_props, face_props;
  long vertices = 0, faces = 0;
  while (std::getline(header, line)) {
    std::istringstream cells(line);
    std::string tag;
    cells >> tag;
    if (tag == "format") cells >> format;
    if (tag == "element") {
      long n;
      cells >> element >> n;
      (element == "vertex" ? vertices : element == "face" ? faces : n) = n;
      if (element != "vertex" && element != "face")
        throw IoError(fmt::format("{}: element '{}' is not supported", b.path, element));
    }
    if (tag == "property") {
      Property p;
      cells >> p.type;
      if (p.type == "list") cells >> p.count_type >> p.type;
      cells >> p.name;
      (element == "vertex" ? vertex_props : face_props).push_back(p);
    }
  }
  if (format != "ascii" && format != "binary_little_endian") {
    throw IoError(
        fmt::format("{}: PLY format '{}' is not ascii or binary_little_endian", b.path, format));
  }
  size_t at = bytes.find('\n', end) + 1;
  std::istringstream text(format == "ascii" ? bytes.substr(at) : std::string());
  // one scalar of `type`, from text or little-endian bytes
  auto scalar = [&](const std::string& type) -> double {
    if (format == "ascii") {
      double x;
      if (!(text >> x)) throw IoError(fmt::format("{}: truncated PLY body", b.path));
      return x;
    }
    const int size = (type == "double" || type == "float64") ? 8
                     : (type == "float" || type == "float32" || type == "int" || type == "int32" ||
                        type == "uint" || type == "uint32")
                         ? 4
                     : (type == "short" || type == "int16" || type == "ushort" || type == "uint16")
                         ? 2
                         : 1;
    if (at + size > bytes.size()) throw IoError(fmt::format("{}: truncated PLY body", b.path));
    const char* p = bytes.data() + at;
    at += size;
    if (type == "double" || type == "float64") {
      double d;
      std::memcpy(&d, p, 8);
      return d;
    }
    if (type == "float" || type == "float32") {
      float x;
      std::memcpy(&x, p, 4);
      return x;
    }
    if (size == 4) {
      int32_t i;
      std::memcpy(&i, p, 4);
      return type[0] == 'u' ? double(uint32_t(i)) : double(i);
    }
    if (size == 2) {
      int16_t i;
      std::memcpy(&i, p, 2);
      return type[0] == 'u' ? double(uint16_t(i)) : double(i);
    }
    return type == "char" || type == "int8" ? double(int8_t(*p)) : double(uint8_t(*p));
  };
  for (long i = 0; i < vertices; ++i) {
    double xyz[3] = {0, 0, 0};
    for (const Property& p : vertex_props) {
      const double x = scalar(p.type);
      if (p.name == "x") xyz[0] = x;
      if (p.name == "y") xyz[1] = x;
      if (p.name == "z") xyz[2] = x;
    }
    b.Vertex(xyz[0], xyz[1], xyz[2], fmt::format("{}: vertex {}", b.path, i));
  }
  for (long i = 0; i < faces; ++i) {
    for (const Property& p : face_props) {
      if (p.count_type.empty()) {
        scalar(p.type);
        continue;
      }
      const long n = long(scalar(p.count_type));
      std::vector<long> idx;
      for (long k = 0; k < n; ++k) idx.push_back(long(scalar(p.type)));
      if (p.name == "vertex_indices" || p.name == "vertex_index")
        b.Polygon(idx, fmt::format("{}: face {}", b.path, i));
    }
  }
  return b.Done();
}

}  // namespace

void AppendCylinder(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double radius_m,
                    int sides, ObjectGeometry* mesh) {
  SONICBOOM_DEMAND(sides >= 3 && radius_m > 0.0 && (p1 - p0).norm() > 0.0);
  const Eigen::Vector3d u = (p1 - p0).normalized(), a = u.unitOrthogonal(), b = u.cross(a);
  // vertices: a ring and its centre at each end, (2 sides + 2) in all
  const Eigen::Index first = mesh->vertices.cols();
  mesh->vertices.conservativeResize(3, first + 2 * (sides + 1));
  Eigen::Index at = first;
  for (const Eigen::Vector3d& end : {p0, p1}) {
    for (int k = 0; k < sides; ++k) {
      const double t = 2 * std::numbers::pi * k / sides;
      mesh->vertices.col(at++) =
          (end + radius_m * (std::cos(t) * a + std::sin(t) * b)).cast<float>();
    }
    mesh->vertices.col(at++) = end.cast<float>();  // cap centre
  }
  // triangles: two per side face, one per side on each cap
  const Eigen::Index faces = mesh->triangles.cols();
  mesh->triangles.conservativeResize(3, faces + 4 * sides);
  const int base = static_cast<int>(first), top = base + sides + 1;
  for (int k = 0; k < sides; ++k) {
    const int n = (k + 1) % sides;
    mesh->triangles.col(faces + 4 * k) << base + k, base + n, top + k;
    mesh->triangles.col(faces + 4 * k + 1) << base + n, top + n, top + k;
    mesh->triangles.col(faces + 4 * k + 2) << base + sides, base + n, base + k;
    mesh->triangles.col(faces + 4 * k + 3) << top + sides, top + k, top + n;
  }
}

void WriteObjectPly(const std::string& path, const ObjectGeometry& object) {
  static_assert(std::endian::native == std::endian::little, "PLY bodies are written as stored");
  std::string body = fmt::format(
      "ply\nformat binary_little_endian 1.0\ncomment sonicboom object, metres, robot base frame\n"
      "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n"
      "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
      object.vertices.cols(), object.triangles.cols());
  // vertices (V x 3 float32), then faces as (count 3, three int32 indices)
  body.append(reinterpret_cast<const char*>(object.vertices.data()),
              sizeof(float) * static_cast<size_t>(object.vertices.size()));
  for (Eigen::Index f = 0; f < object.triangles.cols(); ++f) {
    body.push_back(char(3));
    body.append(reinterpret_cast<const char*>(object.triangles.col(f).data()), 3 * sizeof(int));
  }
  // written beside the target and renamed: a reader never sees half a mesh
  WriteTextAtomic(path, body);
}

ObjectGeometry ReadObjectGeometry(const std::string& path, double scale) {
  if (!(scale > 0.0) || !std::isfinite(scale))
    throw ConfigError(fmt::format("object scale {} must be positive", scale));
  const std::string bytes = ReadAll(path);
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(c));
  const Builder b{path, scale, {}, {}};
  try {
    if (ext == ".ply") return ReadPly(b, bytes);
    if (ext == ".obj") return ReadObj(b, bytes);
    if (ext == ".stl") return ReadStl(b, bytes);
    if (ext == ".pts") return ReadCloudText(b, bytes, /*skip_first=*/true);
    if (ext == ".xyz") return ReadCloudText(b, bytes, /*skip_first=*/false);
  } catch (const std::invalid_argument&) {
    throw IoError(fmt::format("{}: a number is malformed", path));
  } catch (const std::out_of_range&) {
    throw IoError(fmt::format("{}: a number is out of range", path));
  }
  throw IoError(fmt::format("{}: unknown object format '{}' (ply, obj, stl, pts, xyz)", path, ext));
}

}  // namespace sonicboom::hardware
