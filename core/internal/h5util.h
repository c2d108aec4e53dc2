#pragma once
/// Private HDF5 helpers shared by the dataset files (reader, writer, merge, summary) and
/// array_file.cc: owning handles, error checks that become IoError naming the file and the
/// object, attributes, and row-extendable datasets.
/// Only core .cc files include this header; hdf5.h never reaches a public header.

#include <hdf5.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "sonicboom/core/files.h"

namespace sonicboom::internal::h5 {

/// Turns off HDF5's printing of its error stack (once per process); every failure is reported
/// as an exception instead.
void SilenceErrorPrinting();

/// Owns one HDF5 identifier (file, group, dataset, attribute, dataspace, datatype or property
/// list) and closes it with the matching H5*close.
class Handle {
 public:
  Handle() = default;
  explicit Handle(hid_t id) : id_(id) {}
  ~Handle() { Reset(); }
  Handle(Handle&& other) noexcept : id_(other.Release()) {}
  Handle& operator=(Handle&& other) noexcept;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;

  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  /// Gives up ownership without closing.
  hid_t Release();
  /// Closes the identifier (errors while closing are ignored) and becomes empty.
  void Reset();
  /// Closes the identifier and reports a failure as IoError (use for files, where closing
  /// flushes data).
  void Close(std::string_view file, std::string_view object);

 private:
  hid_t id_{H5I_INVALID_HID};
};

/// Throws IoError "<file>: cannot <action> <object> (<innermost HDF5 message>)".
[[noreturn]] void ThrowIo(std::string_view file, std::string_view object, std::string_view action);

/// Returns `id` when it is valid, else throws IoError naming the file, object and action.
hid_t CheckId(hid_t id, std::string_view file, std::string_view object, std::string_view action);
/// Throws IoError when `status` is negative.
void CheckStatus(herr_t status, std::string_view file, std::string_view object,
                 std::string_view action);

/// The name a file is written under until it is complete: "<path>.partial".
std::string PartialPath(const std::string& path);
/// Before writing `path`: IoError when its parent directory does not exist or another process
/// is writing it; removes a stale "<path>.partial". An existing complete file at `path` is left
/// alone. The returned lock is held until the file is committed.
OutputLock PrepareAtomicWrite(const std::string& path);
/// Renames "<path>.partial" over `path`. Throws IoError.
void CommitAtomicWrite(const std::string& path);
/// True when the root of `file` has the attribute `complete` equal to 1.
bool IsComplete(hid_t file, std::string_view file_name);
/// Sets the root attribute `complete` = 1 (uint8), the last write of every file.
void MarkComplete(hid_t file, std::string_view file_name);

/// Creates (truncating) an HDF5 file for writing.
Handle CreateFile(const std::string& path);
/// Opens an existing HDF5 file read-only. IoError "<path>: no such file" when it does not exist,
/// "<path>: not an HDF5 file" when it is something else.
Handle OpenFileReadOnly(const std::string& path);
/// True when `path` exists and carries the HDF5 signature.
bool IsHdf5(const std::string& path);

/// True when every component of the '/'-separated `path` exists below `loc`.
bool PathExists(hid_t loc, std::string_view path);
/// Opens the dataset at `path` below `loc`; IoError "<file>: no dataset <path>" when missing.
Handle OpenDataset(hid_t loc, const std::string& path, std::string_view file);

/// Root or object attributes. Writing replaces an attribute of the same name.
bool HasAttr(hid_t loc, const char* name, std::string_view file);
/// Scalar variable-length UTF-8 string (h5py reads it as str).
void WriteStringAttr(hid_t loc, const char* name, const std::string& value, std::string_view file);
void WriteDoubleAttr(hid_t loc, const char* name, double value, std::string_view file);
void WriteInt64Attr(hid_t loc, const char* name, int64_t value, std::string_view file);
void WriteUint64Attr(hid_t loc, const char* name, uint64_t value, std::string_view file);
void WriteUint8Attr(hid_t loc, const char* name, uint8_t value, std::string_view file);
/// Reads a scalar string attribute, fixed or variable length. IoError when missing or not a
/// string.
std::string ReadStringAttr(hid_t loc, const char* name, std::string_view file);
/// Reads a scalar numeric attribute converted to the requested type. IoError when missing or
/// not numeric.
double ReadDoubleAttr(hid_t loc, const char* name, std::string_view file);
int64_t ReadInt64Attr(hid_t loc, const char* name, std::string_view file);
uint64_t ReadUint64Attr(hid_t loc, const char* name, std::string_view file);

/// One attribute of an object as seen by a generic summary.
struct AttrValue {
  std::string name;
  enum class Kind { kString, kSigned, kUnsigned, kFloat, kOther } kind{Kind::kOther};
  std::string text;            // kString
  int64_t signed_value{0};     // kSigned: scalar signed integer
  uint64_t unsigned_value{0};  // kUnsigned: scalar unsigned integer
  double float_value{0.0};     // kFloat: scalar float
};
/// Every attribute of `loc` in creation-independent (name) order.
std::vector<AttrValue> ListAttrs(hid_t loc, std::string_view file);

/// A variable-length UTF-8 string datatype (caller owns it).
Handle VlenStringType();
/// Readable name of a stored datatype: "int16", "uint64", "float32", "float64", "string", ...
std::string DtypeName(hid_t type);

/// Full paths (with leading '/') of every dataset below the file root, depth first in name order.
std::vector<std::string> ListDatasets(hid_t file, std::string_view file_name);

/// Extent of a dataset, one entry per dimension.
std::vector<hsize_t> Dims(hid_t dataset, std::string_view file, std::string_view object);

/// How an extendable dataset is laid out: rows along the unlimited first dimension, each row of
/// shape `row_dims`; `chunk_rows` rows per chunk; optional shuffle + deflate.
struct ExtendableLayout {
  std::vector<hsize_t> row_dims;
  hsize_t chunk_rows{1024};
  int deflate_level{-1};  // -1: no compression, else shuffle + deflate at this level
};
/// Creates an empty dataset (0 rows) at `path` below `loc`, intermediate groups included.
Handle CreateExtendable(hid_t loc, const std::string& path, hid_t file_type,
                        const ExtendableLayout& layout, std::string_view file);
/// Grows the first dimension by `rows` and writes them from `data` (row-major, memory type
/// `mem_type`).
void AppendRows(hid_t dataset, hid_t mem_type, const void* data, hsize_t rows,
                std::string_view file, std::string_view object);
/// Reads rows [first, first + rows) into `out` (row-major, memory type `mem_type`).
void ReadRows(hid_t dataset, hid_t mem_type, void* out, hsize_t first, hsize_t rows,
              std::string_view file, std::string_view object);
/// Reads rows [first, first + rows) of a 1-D string dataset (fixed or variable length).
std::vector<std::string> ReadStringRows(hid_t dataset, hsize_t first, hsize_t rows,
                                        std::string_view file, std::string_view object);

/// One source of a virtual dataset: all `rows` rows of dataset `dataset` in file `file` (a path
/// relative to the virtual dataset's own file, or absolute), placed at rows start, start + stride,
/// ... of the virtual dataset.
struct VirtualSource {
  std::string file;
  std::string dataset;
  hsize_t rows{0};
  hsize_t start{0};
  hsize_t stride{1};
};
/// Creates a virtual dataset of `rows` rows of shape `row_dims` at `path` below `loc` over
/// `sources` (no data copied: reads go to the sources).
Handle CreateVirtual(hid_t loc, const std::string& path, hid_t file_type, hsize_t rows,
                     const std::vector<hsize_t>& row_dims,
                     const std::vector<VirtualSource>& sources, std::string_view file);
/// The source file names of a virtual dataset as stored (empty for a stored dataset).
std::vector<std::string> VirtualSourceFiles(hid_t dataset, std::string_view file,
                                            std::string_view object);

/// The stored (already filtered, e.g. compressed) bytes of one chunk.
struct RawChunk {
  uint32_t filter_mask{0};  // filters skipped for this chunk, as HDF5 reports them
  std::vector<char> bytes;
};
/// True when both datasets store the same datatype in the same chunk shape through the same
/// filter pipeline, so that raw chunks of one are valid chunks of the other.
bool SameChunkStorage(hid_t a, hid_t b, std::string_view file, std::string_view object);
/// Reads the stored bytes of the chunk starting at `offset` (one entry per dimension).
RawChunk ReadRawChunk(hid_t dataset, const std::vector<hsize_t>& offset, std::string_view file,
                      std::string_view object);
/// Grows the first dimension by one row and stores `size` already-filtered bytes as that row's
/// chunk (filters in `filter_mask` skipped); the dataset must have one row per chunk and each
/// chunk must span the full row.
void AppendRawChunkRow(hid_t dataset, uint32_t filter_mask, const void* bytes, size_t size,
                       std::string_view file, std::string_view object);

/// Writes a whole fixed-size dataset at `path` below `loc` (intermediate groups created).
/// An empty `dims` writes a scalar.
void WriteFixed(hid_t loc, const std::string& path, hid_t file_type, hid_t mem_type,
                const std::vector<hsize_t>& dims, const void* data, std::string_view file);

}  // namespace sonicboom::internal::h5
