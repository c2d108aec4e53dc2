// DatasetReader: the public face of internal::dataset::DatasetFile.
#include <memory>
#include <string>

#include "internal/dataset_file.h"
#include "sonicboom/core/dataset.h"

namespace sonicboom {

using internal::dataset::DatasetFile;

struct DatasetReader::Impl {
  DatasetFile file;
};

DatasetReader::DatasetReader(const std::string& path, bool allow_incomplete)
    : impl_(std::make_unique<Impl>(Impl{DatasetFile(path, allow_incomplete)})) {}

DatasetReader::~DatasetReader() = default;
DatasetReader::DatasetReader(DatasetReader&&) noexcept = default;
DatasetReader& DatasetReader::operator=(DatasetReader&&) noexcept = default;

const DatasetInfo& DatasetReader::info() const {
  return impl_->file.info();
}

int64_t DatasetReader::size() const {
  return impl_->file.size();
}

StrikeSample DatasetReader::ReadMeta(int64_t i) const {
  StrikeSample sample;
  impl_->file.ReadMeta(i, &sample);
  return sample;
}

StrikeSample DatasetReader::Read(int64_t i) const {
  StrikeSample sample;
  impl_->file.ReadMeta(i, &sample);
  sample.audio = impl_->file.ReadAudio(i);
  return sample;
}

}  // namespace sonicboom
