#include "sonicboom/hardware/npy.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"

namespace sonicboom::hardware {
namespace {

constexpr char kMagic[] = "\x93NUMPY";
constexpr size_t kMagicSize = 6;

// The value of `key` in the header dict, up to the next top-level ',' or '}' (a tuple kept
// whole); empty when absent.
std::string HeaderValue(const std::string& header, const std::string& key) {
  const std::string quoted[2] = {"'" + key + "'", "\"" + key + "\""};
  size_t at = std::string::npos;
  for (const std::string& q : quoted) {
    at = header.find(q);
    if (at != std::string::npos) {
      at += q.size();
      break;
    }
  }
  if (at == std::string::npos) return {};
  at = header.find(':', at);
  if (at == std::string::npos) return {};
  ++at;
  int depth = 0;
  size_t end = at;
  for (; end < header.size(); ++end) {
    const char c = header[end];
    if (c == '(' || c == '[') ++depth;
    if (c == ')' || c == ']') --depth;
    if (depth == 0 && (c == ',' || c == '}')) break;
    if (depth < 0) break;
  }
  std::string value = header.substr(at, end - at);
  const size_t first = value.find_first_not_of(" \t");
  const size_t last = value.find_last_not_of(" \t");
  return first == std::string::npos ? std::string() : value.substr(first, last - first + 1);
}

// "(200, 7)" -> {200, 7}; "()" -> {}; "(5,)" -> {5}.
std::vector<int64_t> ParseShape(const std::string& text, const std::string& path) {
  if (text.size() < 2 || text.front() != '(' || text.back() != ')') {
    throw IoError(fmt::format("{}: .npy shape '{}' is not a tuple", path, text));
  }
  std::vector<int64_t> shape;
  std::string cell;
  auto flush = [&] {
    const size_t first = cell.find_first_not_of(" \tL");
    if (first == std::string::npos) {
      cell.clear();
      return;
    }
    size_t used = 0;
    long long v = -1;
    try {
      v = std::stoll(cell.substr(first), &used);
    } catch (const std::exception&) {
      v = -1;
    }
    if (v < 0) throw IoError(fmt::format("{}: .npy shape '{}' has a bad dimension", path, text));
    shape.push_back(v);
    cell.clear();
  };
  for (size_t i = 1; i + 1 < text.size(); ++i) {
    if (text[i] == ',') {
      flush();
    } else {
      cell += text[i];
    }
  }
  flush();
  return shape;
}

// float16 bits -> double
double HalfToDouble(uint16_t h) {
  const int sign = (h >> 15) & 1, exponent = (h >> 10) & 0x1f, mantissa = h & 0x3ff;
  double v;
  if (exponent == 0) {
    v = std::ldexp(mantissa, -24);
  } else if (exponent == 31) {
    v = mantissa ? std::numeric_limits<double>::quiet_NaN()
                 : std::numeric_limits<double>::infinity();
  } else {
    v = std::ldexp(mantissa + 1024, exponent - 25);
  }
  return sign ? -v : v;
}

// One element of `size` bytes of kind f/i/u/b, in the file's byte order, as a double.
double Element(const unsigned char* p, char kind, int size, bool big_endian) {
  unsigned char b[8];
  for (int i = 0; i < size; ++i) b[i] = big_endian ? p[size - 1 - i] : p[i];  // to little
  uint64_t bits = 0;
  for (int i = size - 1; i >= 0; --i) bits = (bits << 8) | b[i];
  switch (kind) {
    case 'b':
      return bits != 0 ? 1.0 : 0.0;
    case 'u':
      return static_cast<double>(bits);
    case 'i': {
      const int shift = 64 - 8 * size;  // sign-extend
      return static_cast<double>(static_cast<int64_t>(bits << shift) >> shift);
    }
    default:
      break;
  }
  if (size == 2) return HalfToDouble(static_cast<uint16_t>(bits));
  if (size == 4) {
    float f;
    const auto u = static_cast<uint32_t>(bits);
    std::memcpy(&f, &u, 4);
    return f;
  }
  double d;
  std::memcpy(&d, &bits, 8);
  return d;
}

}  // namespace

NpyArray ReadNpy(const std::string& path) {
  RequireReadableFile(path);  // a FIFO would block, a device (/dev/zero) never end
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fmt::format("{}: cannot open .npy file", path));
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());

  // magic, version, header length (2 bytes in 1.0, 4 in 2.0 and 3.0)
  if (bytes.size() < 10 || bytes.compare(0, kMagicSize, kMagic, kMagicSize) != 0) {
    throw IoError(fmt::format("{}: not a .npy file (bad magic)", path));
  }
  const auto major = static_cast<unsigned char>(bytes[6]);
  if (major < 1 || major > 3) {
    throw IoError(fmt::format("{}: .npy format version {} is not 1, 2 or 3", path, major));
  }
  const size_t len_bytes = major == 1 ? 2 : 4;
  if (bytes.size() < 8 + len_bytes) throw IoError(fmt::format("{}: truncated .npy header", path));
  size_t header_len = 0;
  for (size_t i = 0; i < len_bytes; ++i) {
    header_len |= static_cast<size_t>(static_cast<unsigned char>(bytes[8 + i])) << (8 * i);
  }
  const size_t data_at = 8 + len_bytes + header_len;
  if (bytes.size() < data_at) throw IoError(fmt::format("{}: truncated .npy header", path));
  const std::string header = bytes.substr(8 + len_bytes, header_len);

  // descr: a plain type string, never a structured (list) dtype or an object array
  NpyArray array;
  const std::string descr = HeaderValue(header, "descr");
  if (descr.size() < 2 || (descr.front() != '\'' && descr.front() != '"')) {
    throw IoError(fmt::format("{}: .npy dtype '{}' is not a plain numeric type", path, descr));
  }
  array.dtype = descr.substr(1, descr.size() - 2);
  const std::string& t = array.dtype;
  if (t.find('O') != std::string::npos) {
    throw IoError(
        fmt::format("{}: .npy holds Python objects (dtype '{}'); pickled arrays are "
                    "refused, save a numeric array instead",
                    path, t));
  }
  const bool order_given =
      t.size() == 3 && (t[0] == '<' || t[0] == '>' || t[0] == '|' || t[0] == '=');
  const char kind = order_given ? t[1] : ' ';
  const int size = order_given ? t[2] - '0' : 0;
  const bool kind_ok =
      (kind == 'f' && (size == 2 || size == 4 || size == 8)) ||
      ((kind == 'i' || kind == 'u') && (size == 1 || size == 2 || size == 4 || size == 8)) ||
      (kind == 'b' && size == 1);
  if (!kind_ok) {
    throw IoError(fmt::format("{}: .npy dtype '{}' is not bool, an integer or a float", path, t));
  }
  const bool big_endian = t[0] == '>';

  // shape and order
  const std::string fortran = HeaderValue(header, "fortran_order");
  if (fortran != "True" && fortran != "False") {
    throw IoError(fmt::format("{}: .npy header has no fortran_order", path));
  }
  array.shape = ParseShape(HeaderValue(header, "shape"), path);
  int64_t count = 1;
  for (int64_t d : array.shape) {
    if (d != 0 && count > std::numeric_limits<int64_t>::max() / 8 / d) {
      throw IoError(fmt::format("{}: .npy shape is too large", path));
    }
    count *= d;
  }
  const size_t payload = bytes.size() - data_at;
  if (payload != static_cast<size_t>(count) * size) {
    throw IoError(fmt::format("{}: .npy payload has {} bytes, shape and dtype '{}' need {}", path,
                              payload, t, count * size));
  }

  // values, transposed from Fortran order when needed
  array.data.resize(count);
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data() + data_at);
  const bool transpose = fortran == "True" && array.shape.size() > 1;
  std::vector<int64_t> index(array.shape.size(), 0);
  for (int64_t k = 0; k < count; ++k) {
    const double v = Element(p + k * size, kind, size, big_endian);
    if (!std::isfinite(v)) {
      throw IoError(fmt::format("{}: .npy element {} is not finite", path, k));
    }
    if (!transpose) {
      array.data[k] = v;
      continue;
    }
    // k walks the first axis fastest; place it at its row-major offset
    int64_t offset = 0;
    for (size_t a = 0; a < index.size(); ++a) offset = offset * array.shape[a] + index[a];
    array.data[offset] = v;
    for (size_t a = 0; a < index.size() && ++index[a] == array.shape[a]; ++a) index[a] = 0;
  }
  return array;
}

void WriteNpy(const std::string& path, const std::vector<int64_t>& shape,
              const std::vector<double>& data) {
  int64_t count = 1;
  for (int64_t d : shape) count *= d;
  if (static_cast<int64_t>(data.size()) != count) {
    throw IoError(
        fmt::format("{}: {} values for a shape of {} elements", path, data.size(), count));
  }
  std::string dims;
  for (int64_t d : shape) dims += fmt::format("{}, ", d);
  if (shape.size() > 1) dims.resize(dims.size() - 1);  // "(200, 7)", but "(2,)" keeps its comma
  if (shape.size() > 1) dims.pop_back();
  std::string header =
      fmt::format("{{'descr': '<f8', 'fortran_order': False, 'shape': ({}), }}", dims);
  // pad with spaces so that the data starts on a 64-byte boundary, newline last
  const size_t total = kMagicSize + 4 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
  header += '\n';

  // magic, version 1.0, little-endian header length, header, then the values little endian
  std::string bytes(kMagic, kMagicSize);
  const auto n = static_cast<uint16_t>(header.size());
  bytes += {char(1), char(0), static_cast<char>(n & 0xff), static_cast<char>(n >> 8)};
  bytes += header;
  for (double v : data) {
    uint64_t bits;
    std::memcpy(&bits, &v, 8);
    for (int i = 0; i < 8; ++i) bytes.push_back(static_cast<char>(bits >> (8 * i)));
  }
  WriteTextAtomic(path, bytes);
}

}  // namespace sonicboom::hardware
