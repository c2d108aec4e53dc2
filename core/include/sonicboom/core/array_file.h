#pragma once
/// Small HDF5 files of named float32 arrays (model weights, normalization statistics, experiment
/// results) for modules that should not see HDF5 headers. Like datasets, such a file is written
/// as "<path>.partial", gets the root attribute `complete` = 1 last, and is then renamed.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace sonicboom {

/// One array: `data` holds product(shape) values in row-major order; an empty shape is a scalar.
struct NamedArray {
  std::string name;  // HDF5 path below the root, e.g. "encoder/weight"
  std::vector<int64_t> shape;
  std::vector<float> data;
};

/// Writes `arrays` (names may contain '/'; groups are created) and root string attributes, with
/// `schema` stored as root attribute "schema". Throws IoError when the parent directory is missing,
/// a name repeats, or an array's data does not match its shape.
void WriteArrayFile(const std::string& path, const std::string& schema,
                    const std::vector<NamedArray>& arrays,
                    const std::vector<std::pair<std::string, std::string>>& string_attrs);

/// Reads one array by name, converted to float32. Throws IoError when the file or the array is
/// missing, SchemaError when the file lacks `complete`.
NamedArray ReadArray(const std::string& path, const std::string& name);

/// Reads a root string attribute (also of an incomplete file). Throws IoError when missing.
std::string ReadStringAttr(const std::string& path, const std::string& name);

/// True when `path` is a regular file with the HDF5 signature.
bool IsHdf5File(const std::string& path);

/// JSON summary of any HDF5 file: "file", "kind": "hdf5", "schema" (null when absent),
/// "complete", "arrays": [{"name", "shape", "dtype"}] for every dataset (recursive), and "attrs":
/// the root attributes (strings longer than 200 characters reported as {"length": n}).
std::string SummarizeH5Json(const std::string& path);

}  // namespace sonicboom
