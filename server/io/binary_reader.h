// Internal to conica_io: reading binary mesh files (Gmsh 2.2 / 4.1 binary, legacy VTK BINARY)
// with the byte offset kept, so that every error can say "file: byte N: what is wrong".
//
// Binary mesh files mix ASCII lines (section names, counts, keywords) with blocks of raw
// numbers. ByteReader reads both from one cursor. Every read checks that the bytes are there;
// counts are checked against what the rest of the file can hold before anything is allocated.
// Errors throw ParseError (io/text_reader.h), turned into a Result by parse_mesh().
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "io/text_reader.h"

namespace conica::io::detail {

class ByteReader {
 public:
  // Reads `data` from byte `offset` on; numbers are little-endian until set_big_endian().
  ByteReader(std::string_view data, std::size_t offset, std::string name)
      : data_(data), pos_(offset), name_(std::move(name)) {}

  // Numbers are read in this byte order from now on.
  void set_big_endian(bool big);
  bool big_endian() const { return big_; }

  std::size_t offset() const { return pos_; }
  std::size_t remaining() const { return data_.size() - pos_; }
  const std::string& name() const { return name_; }

  // "name: byte N: what" at the current offset / at `offset`.
  std::string message(std::string_view what) const { return message_at(pos_, what); }
  std::string message_at(std::size_t offset, std::string_view what) const;
  [[noreturn]] void fail(std::string_view what) const;
  [[noreturn]] void fail_at(std::size_t offset, std::string_view what) const;

  // ---- text lines between the binary blocks
  // Next line (up to '\n', a '\r' before it dropped); false at end of file. `start`, when
  // given, receives the offset of the line's first byte.
  bool next_line(std::string_view* line, std::size_t* start = nullptr);
  // Next line with something on it.
  bool next_nonblank_line(std::string_view* line, std::size_t* start = nullptr);
  // Next non-blank line; throws "unexpected end of file, expected <what>".
  std::string_view expect_line(std::string_view what, std::size_t* start = nullptr);
  // Does the rest of the file begin with `prefix`?
  bool starts_with(std::string_view prefix) const;

  // ---- binary numbers; `what` names the field in the error when the file ends
  std::int32_t i32(std::string_view what);
  std::uint32_t u32(std::string_view what);
  std::int64_t i64(std::string_view what);
  std::uint64_t u64(std::string_view what);
  float f32(std::string_view what);
  double f64(std::string_view what);
  // A finite double / float (widened), else "<what> is not a finite number".
  double finite_f64(std::string_view what);
  double finite_f32(std::string_view what);
  // Raw bytes.
  std::string_view bytes(std::size_t n, std::string_view what);
  void skip(std::size_t n, std::string_view what) { bytes(n, what); }

  // Fails unless `count` records of `record_bytes` each fit in the rest of the file:
  // "<what> <count> needs <bytes> bytes, the file has <remaining> left", at `at` (the count's
  // offset) or, by default, the current offset.
  void need(std::uint64_t count, std::uint64_t record_bytes, std::string_view what,
            std::size_t at = kHere) const;
  static constexpr std::size_t kHere = static_cast<std::size_t>(-1);

 private:
  const char* take(std::size_t n, std::string_view what);
  std::string_view data_;
  std::size_t pos_;
  std::string name_;
  bool big_ = false;
  bool swap_ = false;
};

// The host's byte order.
bool host_is_big_endian();

}  // namespace conica::io::detail
