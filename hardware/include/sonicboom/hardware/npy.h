#pragma once
/// NumPy .npy files (format versions 1.0-3.0) for the published trial layout: numeric arrays
/// only. Object arrays, whose payload is a Python pickle, are refused rather than unpickled.

#include <cstdint>
#include <string>
#include <vector>

namespace sonicboom::hardware {

/// A numeric array read from a .npy file, converted to float64 in C (row-major) order.
struct NpyArray {
  std::vector<int64_t> shape;  // empty: a scalar (one value)
  std::vector<double> data;    // product(shape) values, row-major
  std::string dtype;           // the file's descr, e.g. "<f8", ">i4", "|u1"
  int64_t rows() const { return shape.empty() ? 1 : shape[0]; }
  int64_t cols() const { return shape.size() < 2 ? 1 : shape[1]; }
};

/// Reads `path`. Throws IoError naming the file for: a missing or truncated file, a bad magic or
/// header, a dtype other than bool, (u)int8-64 or float16/32/64 in either byte order (object
/// arrays say that pickles are refused), a payload whose size differs from the shape's, and
/// non-finite values (refused: a label or pose must be a number). Fortran-ordered arrays are
/// transposed into C order.
NpyArray ReadNpy(const std::string& path);

/// Writes a little-endian float64 C-order array (format 1.0) to "<path>.partial" and renames it.
/// Throws IoError; data.size() must equal product(shape).
void WriteNpy(const std::string& path, const std::vector<int64_t>& shape,
              const std::vector<double>& data);

}  // namespace sonicboom::hardware
