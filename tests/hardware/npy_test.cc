// The .npy reader: dtypes, byte orders, Fortran order, and every refusal names the file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>

#include "common/test_util.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/hardware/npy.h"

namespace sonicboom::hardware {
namespace {

using sonicboom::testing::TempDir;
using sonicboom::testing::ThrownMessage;
using ::testing::HasSubstr;

// A version-1.0 .npy file with `header` (padded to 16 bytes) and raw payload bytes.
void WriteRaw(const std::string& path, std::string header, const std::string& payload) {
  while ((10 + header.size() + 1) % 16 != 0) header += ' ';
  header += '\n';
  std::ofstream out(path, std::ios::binary);
  out.write("\x93NUMPY\x01\x00", 8);
  const char len[2] = {static_cast<char>(header.size() & 0xff),
                       static_cast<char>(header.size() >> 8)};
  out.write(len, 2);
  out << header << payload;
}

TEST(NpyTest, WriteThenReadGivesTheSameArray) {
  TempDir dir;
  const std::vector<double> data = {0.1, -2.5, 3e-9, 4.0, 5.5, -6.25};
  WriteNpy(dir / "a.npy", {2, 3}, data);
  const NpyArray a = ReadNpy(dir / "a.npy");
  EXPECT_EQ(a.shape, (std::vector<int64_t>{2, 3}));
  EXPECT_EQ(a.dtype, "<f8");
  EXPECT_EQ(a.data, data);
  WriteNpy(dir / "v.npy", {2}, {0.25, -1.0});
  EXPECT_EQ(ReadNpy(dir / "v.npy").shape, (std::vector<int64_t>{2}));
}

TEST(NpyTest, BigEndianFloat32AndFortranOrderAreConverted) {
  TempDir dir;
  // >f4 values 1.5 and -2.0, shape (2,)
  WriteRaw(dir / "be.npy", "{'descr': '>f4', 'fortran_order': False, 'shape': (2,), }",
           std::string("\x3f\xc0\x00\x00\xc0\x00\x00\x00", 8));
  EXPECT_EQ(ReadNpy(dir / "be.npy").data, (std::vector<double>{1.5, -2.0}));
  // <i2 (2, 3) in Fortran order: column-major 1 4 2 5 3 6 is row-major 1 2 3 4 5 6
  std::string payload;
  for (int v : {1, 4, 2, 5, 3, 6}) payload += std::string{static_cast<char>(v), '\0'};
  WriteRaw(dir / "f.npy", "{'descr': '<i2', 'fortran_order': True, 'shape': (2, 3), }", payload);
  EXPECT_EQ(ReadNpy(dir / "f.npy").data, (std::vector<double>{1, 2, 3, 4, 5, 6}));
}

TEST(NpyTest, RefusesPicklesTruncationNonFiniteAndJunk) {
  TempDir dir;
  WriteRaw(dir / "o.npy", "{'descr': '|O', 'fortran_order': False, 'shape': (2,), }",
           "\x80\x04junk");
  EXPECT_THAT(ThrownMessage<IoError>([&] { ReadNpy(dir / "o.npy"); }),
              HasSubstr("pickled arrays are refused"));
  WriteRaw(dir / "short.npy", "{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }",
           std::string(16, '\0'));
  EXPECT_THAT(ThrownMessage<IoError>([&] { ReadNpy(dir / "short.npy"); }),
              HasSubstr("short.npy: .npy payload has 16 bytes"));
  WriteRaw(dir / "nan.npy", "{'descr': '<f8', 'fortran_order': False, 'shape': (1,), }",
           std::string("\0\0\0\0\0\0\xf8\x7f", 8));
  EXPECT_THAT(ThrownMessage<IoError>([&] { ReadNpy(dir / "nan.npy"); }), HasSubstr("not finite"));
  WriteRaw(dir / "c.npy", "{'descr': '<c16', 'fortran_order': False, 'shape': (1,), }",
           std::string(16, '\0'));
  EXPECT_THAT(ThrownMessage<IoError>([&] { ReadNpy(dir / "c.npy"); }),
              HasSubstr("is not bool, an integer or a float"));
  std::ofstream(dir / "txt.npy") << "0.1 0.2\n";
  EXPECT_THAT(ThrownMessage<IoError>([&] { ReadNpy(dir / "txt.npy"); }), HasSubstr("bad magic"));
  EXPECT_THAT(ThrownMessage<IoError>([&] { ReadNpy(dir / "none.npy"); }),
              HasSubstr("none.npy: no such file"));
}

}  // namespace
}  // namespace sonicboom::hardware
