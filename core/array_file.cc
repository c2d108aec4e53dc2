#include "sonicboom/core/array_file.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <set>
#include <string>

#include "internal/h5util.h"
#include "internal/watchdog.h"
#include "sonicboom/core/errors.h"

namespace sonicboom {
namespace {

namespace h5 = internal::h5;

// Root string attributes longer than this are summarized by their length only.
constexpr size_t kMaxSummarizedAttrChars = 200;

// "(2, 3)" for messages.
std::string ShapeText(const std::vector<int64_t>& shape) {
  std::string text = "(";
  for (size_t d = 0; d < shape.size(); ++d) text += (d > 0 ? ", " : "") + std::to_string(shape[d]);
  return text + ")";
}

// Refuses arrays whose names repeat or whose data do not fill their shape.
void CheckArrays(const std::string& path, const std::vector<NamedArray>& arrays) {
  std::set<std::string> names;
  for (const NamedArray& array : arrays) {
    if (array.name.empty() || array.name.find_first_not_of('/') == std::string::npos) {
      throw IoError(path + ": an array has an empty name");
    }
    if (!names.insert(array.name).second) {
      throw IoError(path + ": array '" + array.name + "' given twice");
    }
    int64_t elements = 1;
    for (int64_t extent : array.shape) {
      if (extent < 0) {
        throw IoError(path + ": array '" + array.name + "' has negative extent in shape " +
                      ShapeText(array.shape));
      }
      elements *= extent;
    }
    if (elements != static_cast<int64_t>(array.data.size())) {
      throw IoError(path + ": array '" + array.name + "' has shape " + ShapeText(array.shape) +
                    " (" + std::to_string(elements) + " values) but " +
                    std::to_string(array.data.size()) + " values");
    }
  }
}

}  // namespace

void WriteArrayFile(const std::string& path, const std::string& schema,
                    const std::vector<NamedArray>& arrays,
                    const std::vector<std::pair<std::string, std::string>>& string_attrs) {
  CheckArrays(path, arrays);
  for (const auto& [name, value] : string_attrs) {
    if (name == "schema" || name == "complete") {
      throw IoError(path + ": root attribute `" + name + "` is reserved");
    }
  }
  const OutputLock lock = h5::PrepareAtomicWrite(path);
  const std::string partial = h5::PartialPath(path);
  h5::Handle file = h5::CreateFile(partial);

  // Root attributes first, then every array as float32 (row-major, shape as given).
  h5::WriteStringAttr(file.get(), "schema", schema, partial);
  for (const auto& [name, value] : string_attrs) {
    h5::WriteStringAttr(file.get(), name.c_str(), value, partial);
  }
  for (const NamedArray& array : arrays) {
    const std::vector<hsize_t> dims(array.shape.begin(), array.shape.end());
    h5::WriteFixed(file.get(), array.name, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, dims,
                   array.data.data(), partial);
  }

  // `complete` last, then close and move into place.
  h5::MarkComplete(file.get(), partial);
  file.Close(partial, "");
  h5::CommitAtomicWrite(path);
}

NamedArray ReadArray(const std::string& path, const std::string& name) {
  std::optional<internal::ReadDeadline> metadata(std::in_place, path + ": reading array " + name);
  h5::Handle file = h5::OpenFileReadOnly(path);
  if (!h5::IsComplete(file.get(), path)) {
    throw SchemaError(path +
                      ": incomplete file (no `complete` attribute): written by a run that did "
                      "not finish");
  }
  h5::Handle dataset = h5::OpenDataset(file.get(), name, path);
  h5::Handle type(h5::CheckId(H5Dget_type(dataset.get()), path, name, "read type of"));
  const H5T_class_t type_class = H5Tget_class(type.get());
  if (type_class != H5T_FLOAT && type_class != H5T_INTEGER) {
    throw IoError(path + ": array " + name + " is not numeric (" + h5::DtypeName(type.get()) + ")");
  }

  // Whole dataset, converted to float32 by the library.
  NamedArray array;
  array.name = name;
  int64_t elements = 1;
  for (hsize_t extent : h5::Dims(dataset.get(), path, name)) {
    array.shape.push_back(static_cast<int64_t>(extent));
    elements *= static_cast<int64_t>(extent);
  }
  array.data.resize(elements);
  metadata.reset();  // the data itself may be large: its read is not timed
  if (elements > 0) {
    h5::CheckStatus(
        H5Dread(dataset.get(), H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, array.data.data()),
        path, name, "read array");
  }
  return array;
}

std::string ReadStringAttr(const std::string& path, const std::string& name) {
  const internal::ReadDeadline deadline(path + ": reading attribute " + name);
  h5::Handle file = h5::OpenFileReadOnly(path);
  return h5::ReadStringAttr(file.get(), name.c_str(), path);
}

bool IsHdf5File(const std::string& path) {
  return h5::IsHdf5(path);
}

std::string SummarizeH5Json(const std::string& path) {
  const internal::ReadDeadline deadline(path + ": reading the file");
  h5::Handle file = h5::OpenFileReadOnly(path);
  nlohmann::ordered_json summary;
  summary["file"] = path;
  summary["kind"] = "hdf5";
  summary["schema"] = nullptr;
  summary["complete"] = h5::IsComplete(file.get(), path);

  // Root attributes: strings (long ones by length) and numeric scalars.
  nlohmann::ordered_json attrs = nlohmann::ordered_json::object();
  for (const h5::AttrValue& attr : h5::ListAttrs(file.get(), path)) {
    switch (attr.kind) {
      case h5::AttrValue::Kind::kString:
        if (attr.name == "schema") summary["schema"] = attr.text;
        if (attr.text.size() > kMaxSummarizedAttrChars) {
          attrs[attr.name] = {{"length", attr.text.size()}};
        } else {
          attrs[attr.name] = attr.text;
        }
        break;
      case h5::AttrValue::Kind::kSigned:
        attrs[attr.name] = attr.signed_value;
        break;
      case h5::AttrValue::Kind::kUnsigned:
        attrs[attr.name] = attr.unsigned_value;
        break;
      case h5::AttrValue::Kind::kFloat:
        attrs[attr.name] = attr.float_value;
        break;
      case h5::AttrValue::Kind::kOther:
        attrs[attr.name] = nullptr;
        break;
    }
  }

  // Every dataset below the root with its shape and stored type.
  nlohmann::ordered_json arrays = nlohmann::ordered_json::array();
  for (const std::string& name : h5::ListDatasets(file.get(), path)) {
    h5::Handle dataset = h5::OpenDataset(file.get(), name, path);
    h5::Handle type(h5::CheckId(H5Dget_type(dataset.get()), path, name, "read type of"));
    nlohmann::ordered_json shape = nlohmann::ordered_json::array();
    for (hsize_t extent : h5::Dims(dataset.get(), path, name)) shape.push_back(extent);
    arrays.push_back({{"name", name}, {"shape", shape}, {"dtype", h5::DtypeName(type.get())}});
  }
  summary["arrays"] = arrays;
  summary["attrs"] = attrs;
  return summary.dump(2);
}

}  // namespace sonicboom
