#include "internal/h5util.h"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>

#include "sonicboom/core/errors.h"

namespace sonicboom::internal::h5 {
namespace {

// Joins "<file>: <rest>" for error messages.
std::string Located(std::string_view file, std::string_view rest) {
  std::string message(file);
  message += ": ";
  message += rest;
  return message;
}

// The most specific message on the current thread's HDF5 error stack, then clears the stack.
std::string InnermostHdf5Message() {
  std::string message;
  auto visit = [](unsigned n, const H5E_error2_t* error, void* data) -> herr_t {
    if (n == 0 && error->desc != nullptr) *static_cast<std::string*>(data) = error->desc;
    return 0;
  };
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, visit, &message);
  H5Eclear2(H5E_DEFAULT);
  return message;
}

// Writes one scalar attribute of any numeric type, replacing an existing one.
void WriteScalarAttr(hid_t loc, const char* name, hid_t file_type, hid_t mem_type,
                     const void* value, std::string_view file) {
  if (HasAttr(loc, name, file)) {
    CheckStatus(H5Adelete(loc, name), file, name, "replace attribute");
  }
  Handle space(CheckId(H5Screate(H5S_SCALAR), file, name, "create dataspace for attribute"));
  Handle attr(CheckId(H5Acreate2(loc, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT), file,
                      name, "create attribute"));
  CheckStatus(H5Awrite(attr.get(), mem_type, value), file, name, "write attribute");
}

// Opens an attribute that must hold exactly one element; IoError when missing.
Handle OpenScalarAttr(hid_t loc, const char* name, std::string_view file) {
  if (!HasAttr(loc, name, file)) {
    throw IoError(Located(file, std::string("missing attribute `") + name + "`"));
  }
  Handle attr(CheckId(H5Aopen(loc, name, H5P_DEFAULT), file, name, "open attribute"));
  Handle space(CheckId(H5Aget_space(attr.get()), file, name, "read dataspace of attribute"));
  const hssize_t points = H5Sget_simple_extent_npoints(space.get());
  if (points != 1) {
    throw IoError(Located(file, std::string("attribute `") + name + "` holds " +
                                    std::to_string(points) + " values, expected 1"));
  }
  return attr;
}

// Reads a one-element numeric attribute converted to `mem_type`.
void ReadNumericAttr(hid_t loc, const char* name, hid_t mem_type, void* out,
                     std::string_view file) {
  Handle attr = OpenScalarAttr(loc, name, file);
  Handle type(CheckId(H5Aget_type(attr.get()), file, name, "read type of attribute"));
  const H5T_class_t type_class = H5Tget_class(type.get());
  if (type_class != H5T_INTEGER && type_class != H5T_FLOAT) {
    throw IoError(Located(file, std::string("attribute `") + name + "` is not a number"));
  }
  CheckStatus(H5Aread(attr.get(), mem_type, out), file, name, "read attribute");
}

// A memory string type matching the character set of the stored type `file_type`.
Handle VlenStringTypeLike(hid_t file_type, std::string_view file, std::string_view object) {
  Handle type(CheckId(H5Tcopy(H5T_C_S1), file, object, "create string type"));
  CheckStatus(H5Tset_size(type.get(), H5T_VARIABLE), file, object, "create string type");
  CheckStatus(H5Tset_cset(type.get(), H5Tget_cset(file_type)), file, object, "create string type");
  return type;
}

// Fixed-length string bytes up to the first NUL (or the whole field when none).
std::string TrimFixed(const char* field, size_t size) {
  const void* nul = std::memchr(field, '\0', size);
  return std::string(field, nul == nullptr ? size : static_cast<const char*>(nul) - field);
}

// A link-creation property list that creates missing intermediate groups.
Handle IntermediateGroupsLcpl(std::string_view file, std::string_view object) {
  Handle lcpl(CheckId(H5Pcreate(H5P_LINK_CREATE), file, object, "create link properties"));
  CheckStatus(H5Pset_create_intermediate_group(lcpl.get(), 1), file, object,
              "create link properties");
  return lcpl;
}

// Selects rows [first, first + rows) of a dataset whose rows have shape dims[1:].
Handle SelectRows(hid_t dataset, const std::vector<hsize_t>& dims, hsize_t first, hsize_t rows,
                  std::string_view file, std::string_view object) {
  Handle space(CheckId(H5Dget_space(dataset), file, object, "read dataspace of"));
  std::vector<hsize_t> start(dims.size(), 0);
  std::vector<hsize_t> count = dims;
  start[0] = first;
  count[0] = rows;
  CheckStatus(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(),
                                  nullptr),
              file, object, "select rows of");
  return space;
}

// Number of elements in a block of `rows` rows of shape dims[1:].
hsize_t Elements(const std::vector<hsize_t>& dims, hsize_t rows) {
  hsize_t n = rows;
  for (size_t d = 1; d < dims.size(); ++d) n *= dims[d];
  return n;
}

}  // namespace

namespace {
// No library shutdown at exit: a file whose close failed (a full disk) stays open inside
// libhdf5, and its shutdown would try again and crash after the error was reported. The
// process's files are closed by the kernel; what was written is what a .partial holds.
// Must run before any other call into the library, hence a static initializer.
[[maybe_unused]] const bool kNoShutdownAtExit = H5dont_atexit() >= 0;
}  // namespace

void SilenceErrorPrinting() {
  // The library is thread-safe, so the automatic printing setting is per thread.
  thread_local bool silenced = false;
  if (!silenced) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    silenced = true;
  }
}

Handle& Handle::operator=(Handle&& other) noexcept {
  if (this != &other) {
    Reset();
    id_ = other.Release();
  }
  return *this;
}

hid_t Handle::Release() {
  const hid_t id = id_;
  id_ = H5I_INVALID_HID;
  return id;
}

void Handle::Reset() {
  if (id_ < 0) return;
  switch (H5Iget_type(id_)) {
    case H5I_FILE:
      H5Fclose(id_);
      break;
    case H5I_GROUP:
      H5Gclose(id_);
      break;
    case H5I_DATATYPE:
      H5Tclose(id_);
      break;
    case H5I_DATASPACE:
      H5Sclose(id_);
      break;
    case H5I_DATASET:
      H5Dclose(id_);
      break;
    case H5I_ATTR:
      H5Aclose(id_);
      break;
    case H5I_GENPROP_LST:
      H5Pclose(id_);
      break;
    default:
      break;
  }
  id_ = H5I_INVALID_HID;
}

void Handle::Close(std::string_view file, std::string_view object) {
  if (id_ < 0) return;
  const hid_t id = Release();
  herr_t status = 0;
  switch (H5Iget_type(id)) {
    case H5I_FILE:
      status = H5Fclose(id);
      break;
    case H5I_DATASET:
      status = H5Dclose(id);
      break;
    case H5I_GROUP:
      status = H5Gclose(id);
      break;
    default:
      status = H5Idec_ref(id) < 0 ? -1 : 0;
      break;
  }
  CheckStatus(status, file, object, "close");
}

void ThrowIo(std::string_view file, std::string_view object, std::string_view action) {
  std::string message = Located(file, "cannot ");
  message += action;
  if (!object.empty()) {
    message += " ";
    message += object;
  }
  const std::string detail = InnermostHdf5Message();
  // a full disk is said in words (libhdf5's message is a page of buffer addresses)
  if (detail.find("errno = 28,") != std::string::npos) {
    throw IoError(message + ": no space left on device (the disk is full)");
  }
  if (!detail.empty()) message += " (HDF5: " + detail + ")";
  throw IoError(message);
}

hid_t CheckId(hid_t id, std::string_view file, std::string_view object, std::string_view action) {
  if (id < 0) ThrowIo(file, object, action);
  return id;
}

void CheckStatus(herr_t status, std::string_view file, std::string_view object,
                 std::string_view action) {
  if (status < 0) ThrowIo(file, object, action);
}

std::string PartialPath(const std::string& path) {
  return path + ".partial";
}

OutputLock PrepareAtomicWrite(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty() && !fs::is_directory(parent, ec)) {
    throw IoError(path + ": parent directory " + parent.string() + " does not exist");
  }
  OutputLock lock(path);  // before the stale partial goes: it may be another writer's
  const std::string partial = PartialPath(path);
  fs::remove(partial, ec);
  if (ec) throw IoError(partial + ": cannot remove stale file: " + ec.message());
  return lock;
}

void CommitAtomicWrite(const std::string& path) {
  std::error_code ec;
  std::filesystem::rename(PartialPath(path), path, ec);
  if (ec) throw IoError(PartialPath(path) + ": cannot rename to " + path + ": " + ec.message());
}

bool IsComplete(hid_t file, std::string_view file_name) {
  return HasAttr(file, "complete", file_name) && ReadInt64Attr(file, "complete", file_name) == 1;
}

void MarkComplete(hid_t file, std::string_view file_name) {
  WriteUint8Attr(file, "complete", 1, file_name);
}

Handle CreateFile(const std::string& path) {
  SilenceErrorPrinting();
  return Handle(CheckId(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), path, "",
                        "create HDF5 file"));
}

Handle OpenFileReadOnly(const std::string& path) {
  SilenceErrorPrinting();
  RequireReadableFile(path);
  if (H5Fis_hdf5(path.c_str()) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    throw IoError(path + ": not an HDF5 file");
  }
  return Handle(
      CheckId(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), path, "", "open HDF5 file"));
}

bool IsHdf5(const std::string& path) {
  SilenceErrorPrinting();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  const htri_t is_hdf5 = H5Fis_hdf5(path.c_str());
  H5Eclear2(H5E_DEFAULT);
  return is_hdf5 > 0;
}

bool PathExists(hid_t loc, std::string_view path) {
  // Check each prefix "a", "a/b", ... so a missing group is not an HDF5 error.
  std::string prefix;
  size_t begin = 0;
  while (begin <= path.size()) {
    size_t end = path.find('/', begin);
    if (end == std::string_view::npos) end = path.size();
    if (end > begin) {
      if (!prefix.empty()) prefix += '/';
      prefix += path.substr(begin, end - begin);
      const htri_t exists = H5Lexists(loc, prefix.c_str(), H5P_DEFAULT);
      if (exists <= 0) {
        H5Eclear2(H5E_DEFAULT);
        return false;
      }
    }
    begin = end + 1;
  }
  return !prefix.empty();
}

Handle OpenDataset(hid_t loc, const std::string& path, std::string_view file) {
  if (!PathExists(loc, path)) throw IoError(Located(file, "no dataset " + path));
  return Handle(CheckId(H5Dopen2(loc, path.c_str(), H5P_DEFAULT), file, path, "open dataset"));
}

bool HasAttr(hid_t loc, const char* name, std::string_view file) {
  const htri_t exists = H5Aexists(loc, name);
  if (exists < 0) ThrowIo(file, name, "look up attribute");
  return exists > 0;
}

void WriteStringAttr(hid_t loc, const char* name, const std::string& value, std::string_view file) {
  Handle type = VlenStringType();
  const char* text = value.c_str();
  WriteScalarAttr(loc, name, type.get(), type.get(), &text, file);
}

void WriteDoubleAttr(hid_t loc, const char* name, double value, std::string_view file) {
  WriteScalarAttr(loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value, file);
}

void WriteInt64Attr(hid_t loc, const char* name, int64_t value, std::string_view file) {
  WriteScalarAttr(loc, name, H5T_STD_I64LE, H5T_NATIVE_INT64, &value, file);
}

void WriteUint64Attr(hid_t loc, const char* name, uint64_t value, std::string_view file) {
  WriteScalarAttr(loc, name, H5T_STD_U64LE, H5T_NATIVE_UINT64, &value, file);
}

void WriteUint8Attr(hid_t loc, const char* name, uint8_t value, std::string_view file) {
  WriteScalarAttr(loc, name, H5T_STD_U8LE, H5T_NATIVE_UINT8, &value, file);
}

std::string ReadStringAttr(hid_t loc, const char* name, std::string_view file) {
  Handle attr = OpenScalarAttr(loc, name, file);
  Handle type(CheckId(H5Aget_type(attr.get()), file, name, "read type of attribute"));
  if (H5Tget_class(type.get()) != H5T_STRING) {
    throw IoError(Located(file, std::string("attribute `") + name + "` is not a string"));
  }
  // Variable-length strings come back as a library-allocated char*.
  if (H5Tis_variable_str(type.get()) > 0) {
    Handle mem_type = VlenStringTypeLike(type.get(), file, name);
    char* text = nullptr;
    CheckStatus(H5Aread(attr.get(), mem_type.get(), &text), file, name, "read attribute");
    std::string value = text == nullptr ? std::string() : std::string(text);
    H5free_memory(text);
    return value;
  }
  const size_t size = H5Tget_size(type.get());
  std::string buffer(size, '\0');
  CheckStatus(H5Aread(attr.get(), type.get(), buffer.data()), file, name, "read attribute");
  return TrimFixed(buffer.data(), size);
}

double ReadDoubleAttr(hid_t loc, const char* name, std::string_view file) {
  double value = 0.0;
  ReadNumericAttr(loc, name, H5T_NATIVE_DOUBLE, &value, file);
  return value;
}

int64_t ReadInt64Attr(hid_t loc, const char* name, std::string_view file) {
  int64_t value = 0;
  ReadNumericAttr(loc, name, H5T_NATIVE_INT64, &value, file);
  return value;
}

uint64_t ReadUint64Attr(hid_t loc, const char* name, std::string_view file) {
  uint64_t value = 0;
  ReadNumericAttr(loc, name, H5T_NATIVE_UINT64, &value, file);
  return value;
}

std::vector<AttrValue> ListAttrs(hid_t loc, std::string_view file) {
  // Collect names first: exceptions must not unwind through the HDF5 iteration.
  std::vector<std::string> names;
  auto collect = [](hid_t, const char* name, const H5A_info_t*, void* data) -> herr_t {
    static_cast<std::vector<std::string>*>(data)->emplace_back(name);
    return 0;
  };
  hsize_t position = 0;
  CheckStatus(H5Aiterate2(loc, H5_INDEX_NAME, H5_ITER_INC, &position, collect, &names), file, "",
              "list attributes of");
  std::vector<AttrValue> values;
  for (const std::string& name : names) {
    AttrValue value;
    value.name = name;
    Handle attr(CheckId(H5Aopen(loc, name.c_str(), H5P_DEFAULT), file, name, "open attribute"));
    Handle type(CheckId(H5Aget_type(attr.get()), file, name, "read type of attribute"));
    Handle space(CheckId(H5Aget_space(attr.get()), file, name, "read dataspace of attribute"));
    const bool single = H5Sget_simple_extent_npoints(space.get()) == 1;
    const H5T_class_t type_class = H5Tget_class(type.get());
    if (single && type_class == H5T_STRING) {
      value.kind = AttrValue::Kind::kString;
      value.text = ReadStringAttr(loc, name.c_str(), file);
    } else if (single && type_class == H5T_INTEGER && H5Tget_sign(type.get()) == H5T_SGN_NONE) {
      value.kind = AttrValue::Kind::kUnsigned;
      value.unsigned_value = ReadUint64Attr(loc, name.c_str(), file);
    } else if (single && type_class == H5T_INTEGER) {
      value.kind = AttrValue::Kind::kSigned;
      value.signed_value = ReadInt64Attr(loc, name.c_str(), file);
    } else if (single && type_class == H5T_FLOAT) {
      value.kind = AttrValue::Kind::kFloat;
      value.float_value = ReadDoubleAttr(loc, name.c_str(), file);
    }
    values.push_back(std::move(value));
  }
  return values;
}

Handle VlenStringType() {
  Handle type(H5Tcopy(H5T_C_S1));
  if (!type.valid() || H5Tset_size(type.get(), H5T_VARIABLE) < 0 ||
      H5Tset_cset(type.get(), H5T_CSET_UTF8) < 0) {
    ThrowIo("HDF5", "variable-length string type", "create");
  }
  return type;
}

std::string DtypeName(hid_t type) {
  const size_t bits = 8 * H5Tget_size(type);
  switch (H5Tget_class(type)) {
    case H5T_INTEGER:
      return (H5Tget_sign(type) == H5T_SGN_NONE ? "uint" : "int") + std::to_string(bits);
    case H5T_FLOAT:
      return "float" + std::to_string(bits);
    case H5T_STRING:
      return "string";
    case H5T_COMPOUND:
      return "compound";
    case H5T_ENUM:
      return "enum";
    default:
      return "other";
  }
}

std::vector<std::string> ListDatasets(hid_t file, std::string_view file_name) {
  // Collect every hard link below the root, then keep those that are datasets.
  std::vector<std::string> links;
  auto collect = [](hid_t, const char* name, const H5L_info_t* info, void* data) -> herr_t {
    if (info->type == H5L_TYPE_HARD) {
      static_cast<std::vector<std::string>*>(data)->emplace_back(name);
    }
    return 0;
  };
  CheckStatus(H5Lvisit(file, H5_INDEX_NAME, H5_ITER_INC, collect, &links), file_name, "",
              "list objects of");
  std::vector<std::string> datasets;
  for (const std::string& link : links) {
    Handle object(
        CheckId(H5Oopen(file, link.c_str(), H5P_DEFAULT), file_name, link, "open object"));
    if (H5Iget_type(object.get()) == H5I_DATASET) datasets.push_back("/" + link);
  }
  return datasets;
}

std::vector<hsize_t> Dims(hid_t dataset, std::string_view file, std::string_view object) {
  Handle space(CheckId(H5Dget_space(dataset), file, object, "read dataspace of"));
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) ThrowIo(file, object, "read rank of");
  std::vector<hsize_t> dims(rank, 0);
  if (rank > 0) {
    CheckStatus(H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr), file, object,
                "read extent of");
  }
  return dims;
}

Handle CreateExtendable(hid_t loc, const std::string& path, hid_t file_type,
                        const ExtendableLayout& layout, std::string_view file) {
  // Shape (0, row_dims...) growing without limit along rows; a zero-size row dimension is
  // also left unlimited so that its chunk extent of 1 is legal.
  const size_t rank = layout.row_dims.size() + 1;
  std::vector<hsize_t> dims(rank, 0), max_dims(rank, H5S_UNLIMITED), chunk(rank, 1);
  chunk[0] = std::max<hsize_t>(layout.chunk_rows, 1);
  for (size_t d = 1; d < rank; ++d) {
    dims[d] = layout.row_dims[d - 1];
    if (dims[d] > 0) max_dims[d] = dims[d];
    chunk[d] = std::max<hsize_t>(dims[d], 1);
  }
  Handle space(CheckId(H5Screate_simple(static_cast<int>(rank), dims.data(), max_dims.data()), file,
                       path, "create dataspace for"));
  Handle dcpl(CheckId(H5Pcreate(H5P_DATASET_CREATE), file, path, "create properties for"));
  CheckStatus(H5Pset_chunk(dcpl.get(), static_cast<int>(rank), chunk.data()), file, path,
              "set chunking of");
  if (layout.deflate_level >= 0) {
    CheckStatus(H5Pset_shuffle(dcpl.get()), file, path, "set shuffle filter of");
    CheckStatus(H5Pset_deflate(dcpl.get(), static_cast<unsigned>(layout.deflate_level)), file, path,
                "set deflate filter of");
  }
  Handle lcpl = IntermediateGroupsLcpl(file, path);
  return Handle(CheckId(
      H5Dcreate2(loc, path.c_str(), file_type, space.get(), lcpl.get(), dcpl.get(), H5P_DEFAULT),
      file, path, "create dataset"));
}

Handle CreateVirtual(hid_t loc, const std::string& path, hid_t file_type, hsize_t rows,
                     const std::vector<hsize_t>& row_dims,
                     const std::vector<VirtualSource>& sources, std::string_view file) {
  const size_t rank = row_dims.size() + 1;
  std::vector<hsize_t> dims(rank, rows);
  for (size_t d = 1; d < rank; ++d) dims[d] = row_dims[d - 1];
  Handle space(CheckId(H5Screate_simple(static_cast<int>(rank), dims.data(), nullptr), file, path,
                       "create dataspace for"));
  Handle dcpl(CheckId(H5Pcreate(H5P_DATASET_CREATE), file, path, "create properties for"));
  for (const VirtualSource& source : sources) {
    // the source's rows, whole, into every stride-th row of the virtual dataset
    std::vector<hsize_t> source_dims = dims;
    source_dims[0] = source.rows;
    Handle source_space(
        CheckId(H5Screate_simple(static_cast<int>(rank), source_dims.data(), nullptr), file, path,
                "create source dataspace for"));
    std::vector<hsize_t> start(rank, 0), stride(rank, 1), count(rank, 1), block = dims;
    start[0] = source.start;
    stride[0] = source.stride;
    count[0] = source.rows;
    block[0] = 1;
    CheckStatus(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start.data(), stride.data(),
                                    count.data(), block.data()),
                file, path, "select the rows of a source in");
    CheckStatus(H5Pset_virtual(dcpl.get(), space.get(), source.file.c_str(), source.dataset.c_str(),
                               source_space.get()),
                file, path, "map a source into");
  }
  CheckStatus(H5Sselect_all(space.get()), file, path, "select all of");
  Handle lcpl = IntermediateGroupsLcpl(file, path);
  return Handle(CheckId(
      H5Dcreate2(loc, path.c_str(), file_type, space.get(), lcpl.get(), dcpl.get(), H5P_DEFAULT),
      file, path, "create virtual dataset"));
}

std::vector<std::string> VirtualSourceFiles(hid_t dataset, std::string_view file,
                                            std::string_view object) {
  Handle dcpl(CheckId(H5Dget_create_plist(dataset), file, object, "read properties of"));
  if (H5Pget_layout(dcpl.get()) != H5D_VIRTUAL) return {};
  size_t count = 0;
  CheckStatus(H5Pget_virtual_count(dcpl.get(), &count), file, object, "count the sources of");
  std::vector<std::string> names;
  for (size_t i = 0; i < count; ++i) {
    const ssize_t length = H5Pget_virtual_filename(dcpl.get(), i, nullptr, 0);
    if (length < 0) CheckStatus(-1, file, object, "read a source file name of");
    std::string name(static_cast<size_t>(length) + 1, '\0');
    H5Pget_virtual_filename(dcpl.get(), i, name.data(), name.size());
    name.resize(static_cast<size_t>(length));
    names.push_back(name);
  }
  return names;
}

void AppendRows(hid_t dataset, hid_t mem_type, const void* data, hsize_t rows,
                std::string_view file, std::string_view object) {
  if (rows == 0) return;
  // Handles may be used on another thread than the one that opened the file.
  SilenceErrorPrinting();
  std::vector<hsize_t> dims = Dims(dataset, file, object);
  const hsize_t first = dims[0];
  dims[0] += rows;
  CheckStatus(H5Dset_extent(dataset, dims.data()), file, object, "extend dataset");
  // Rows of zero elements (a zero-size row dimension) only grow the extent.
  if (Elements(dims, rows) == 0) return;
  Handle file_space = SelectRows(dataset, dims, first, rows, file, object);
  std::vector<hsize_t> block = dims;
  block[0] = rows;
  Handle mem_space(CheckId(H5Screate_simple(static_cast<int>(block.size()), block.data(), nullptr),
                           file, object, "create memory dataspace for"));
  CheckStatus(H5Dwrite(dataset, mem_type, mem_space.get(), file_space.get(), H5P_DEFAULT, data),
              file, object, "write rows of");
}

void ReadRows(hid_t dataset, hid_t mem_type, void* out, hsize_t first, hsize_t rows,
              std::string_view file, std::string_view object) {
  if (rows == 0) return;
  SilenceErrorPrinting();
  const std::vector<hsize_t> dims = Dims(dataset, file, object);
  if (dims.empty() || first + rows > dims[0]) {
    throw IoError(Located(file, std::string(object) + " has " +
                                    std::to_string(dims.empty() ? 0 : dims[0]) +
                                    " rows, cannot read rows [" + std::to_string(first) + ", " +
                                    std::to_string(first + rows) + ")"));
  }
  if (Elements(dims, rows) == 0) return;
  Handle file_space = SelectRows(dataset, dims, first, rows, file, object);
  std::vector<hsize_t> block = dims;
  block[0] = rows;
  Handle mem_space(CheckId(H5Screate_simple(static_cast<int>(block.size()), block.data(), nullptr),
                           file, object, "create memory dataspace for"));
  CheckStatus(H5Dread(dataset, mem_type, mem_space.get(), file_space.get(), H5P_DEFAULT, out), file,
              object, "read rows of");
}

std::vector<std::string> ReadStringRows(hid_t dataset, hsize_t first, hsize_t rows,
                                        std::string_view file, std::string_view object) {
  std::vector<std::string> values;
  if (rows == 0) return values;
  Handle type(CheckId(H5Dget_type(dataset), file, object, "read type of"));
  if (H5Tget_class(type.get()) != H5T_STRING) {
    throw IoError(Located(file, std::string(object) + " is not a string dataset"));
  }
  values.reserve(rows);
  // Variable-length strings: the library allocates each one; reclaim them after copying.
  if (H5Tis_variable_str(type.get()) > 0) {
    Handle mem_type = VlenStringTypeLike(type.get(), file, object);
    std::vector<char*> texts(rows, nullptr);
    ReadRows(dataset, mem_type.get(), texts.data(), first, rows, file, object);
    for (const char* text : texts) values.emplace_back(text == nullptr ? "" : text);
    const hsize_t count = rows;
    Handle mem_space(
        CheckId(H5Screate_simple(1, &count, nullptr), file, object, "create memory dataspace for"));
    H5Dvlen_reclaim(mem_type.get(), mem_space.get(), H5P_DEFAULT, texts.data());
    return values;
  }
  const size_t size = H5Tget_size(type.get());
  std::vector<char> buffer(size * rows, '\0');
  ReadRows(dataset, type.get(), buffer.data(), first, rows, file, object);
  for (hsize_t r = 0; r < rows; ++r) values.push_back(TrimFixed(buffer.data() + r * size, size));
  return values;
}

bool SameChunkStorage(hid_t a, hid_t b, std::string_view file, std::string_view object) {
  Handle type_a(CheckId(H5Dget_type(a), file, object, "read type of"));
  Handle type_b(CheckId(H5Dget_type(b), file, object, "read type of"));
  if (H5Tequal(type_a.get(), type_b.get()) <= 0) return false;
  Handle dcpl_a(CheckId(H5Dget_create_plist(a), file, object, "read properties of"));
  Handle dcpl_b(CheckId(H5Dget_create_plist(b), file, object, "read properties of"));
  if (H5Pget_layout(dcpl_a.get()) != H5D_CHUNKED || H5Pget_layout(dcpl_b.get()) != H5D_CHUNKED) {
    return false;
  }
  // Chunk shapes.
  constexpr int kMaxRank = 32;
  hsize_t chunk_a[kMaxRank] = {}, chunk_b[kMaxRank] = {};
  const int rank_a = H5Pget_chunk(dcpl_a.get(), kMaxRank, chunk_a);
  const int rank_b = H5Pget_chunk(dcpl_b.get(), kMaxRank, chunk_b);
  if (rank_a < 0 || rank_a != rank_b || !std::equal(chunk_a, chunk_a + rank_a, chunk_b)) {
    return false;
  }
  // Filter pipelines: same filters with the same parameters, in the same order.
  const int filters = H5Pget_nfilters(dcpl_a.get());
  if (filters < 0 || filters != H5Pget_nfilters(dcpl_b.get())) return false;
  for (int f = 0; f < filters; ++f) {
    unsigned flags_a = 0, flags_b = 0, config_a = 0, config_b = 0;
    size_t values_a = 16, values_b = 16;
    unsigned cd_a[16] = {}, cd_b[16] = {};
    const H5Z_filter_t id_a =
        H5Pget_filter2(dcpl_a.get(), f, &flags_a, &values_a, cd_a, 0, nullptr, &config_a);
    const H5Z_filter_t id_b =
        H5Pget_filter2(dcpl_b.get(), f, &flags_b, &values_b, cd_b, 0, nullptr, &config_b);
    if (id_a < 0 || id_a != id_b || values_a != values_b ||
        !std::equal(cd_a, cd_a + std::min<size_t>(values_a, 16), cd_b)) {
      return false;
    }
  }
  return true;
}

RawChunk ReadRawChunk(hid_t dataset, const std::vector<hsize_t>& offset, std::string_view file,
                      std::string_view object) {
  hsize_t size = 0;
  CheckStatus(H5Dget_chunk_storage_size(dataset, offset.data(), &size), file, object,
              "read chunk size of");
  RawChunk chunk;
  chunk.bytes.resize(size);
  CheckStatus(
      H5Dread_chunk(dataset, H5P_DEFAULT, offset.data(), &chunk.filter_mask, chunk.bytes.data()),
      file, object, "read raw chunk of");
  return chunk;
}

void AppendRawChunkRow(hid_t dataset, uint32_t filter_mask, const void* bytes, size_t size,
                       std::string_view file, std::string_view object) {
  SilenceErrorPrinting();
  std::vector<hsize_t> dims = Dims(dataset, file, object);
  std::vector<hsize_t> offset(dims.size(), 0);
  offset[0] = dims[0];
  dims[0] += 1;
  CheckStatus(H5Dset_extent(dataset, dims.data()), file, object, "extend dataset");
  CheckStatus(H5Dwrite_chunk(dataset, H5P_DEFAULT, filter_mask, offset.data(), size, bytes), file,
              object, "write raw chunk of");
}

void WriteFixed(hid_t loc, const std::string& path, hid_t file_type, hid_t mem_type,
                const std::vector<hsize_t>& dims, const void* data, std::string_view file) {
  Handle space(CheckId(dims.empty()
                           ? H5Screate(H5S_SCALAR)
                           : H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr),
                       file, path, "create dataspace for"));
  Handle lcpl = IntermediateGroupsLcpl(file, path);
  Handle dataset(CheckId(
      H5Dcreate2(loc, path.c_str(), file_type, space.get(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT),
      file, path, "create dataset"));
  hsize_t elements = 1;
  for (hsize_t d : dims) elements *= d;
  if (elements == 0) return;
  CheckStatus(H5Dwrite(dataset.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), file, path,
              "write dataset");
}

}  // namespace sonicboom::internal::h5
