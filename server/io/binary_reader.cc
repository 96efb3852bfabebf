#include "io/binary_reader.h"

#include <cmath>
#include <cstring>

namespace conica::io::detail {

namespace {

template <class T>
T load(const char* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  }
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

}  // namespace

bool host_is_big_endian() {
  const std::uint16_t one = 1;
  unsigned char first;
  std::memcpy(&first, &one, 1);
  return first == 0;
}

void ByteReader::set_big_endian(bool big) {
  big_ = big;
  swap_ = big != host_is_big_endian();
}

std::string ByteReader::message_at(std::size_t offset, std::string_view what) const {
  return name_ + ": byte " + std::to_string(offset) + ": " + std::string(what);
}

void ByteReader::fail(std::string_view what) const { throw ParseError{message(what)}; }

void ByteReader::fail_at(std::size_t offset, std::string_view what) const {
  throw ParseError{message_at(offset, what)};
}

bool ByteReader::next_line(std::string_view* line, std::size_t* start) {
  if (pos_ >= data_.size()) return false;
  if (start) *start = pos_;
  const std::size_t end = data_.find('\n', pos_);
  const std::size_t stop = end == std::string_view::npos ? data_.size() : end;
  std::string_view l = data_.substr(pos_, stop - pos_);
  if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
  pos_ = end == std::string_view::npos ? data_.size() : end + 1;
  *line = l;
  return true;
}

bool ByteReader::next_nonblank_line(std::string_view* line, std::size_t* start) {
  while (next_line(line, start)) {
    if (!Fields(*line).rest().empty()) return true;
  }
  return false;
}

std::string_view ByteReader::expect_line(std::string_view what, std::size_t* start) {
  std::string_view line;
  if (!next_nonblank_line(&line, start)) {
    fail("unexpected end of file, expected " + std::string(what));
  }
  return line;
}

bool ByteReader::starts_with(std::string_view prefix) const {
  return data_.substr(pos_).substr(0, prefix.size()) == prefix;
}

const char* ByteReader::take(std::size_t n, std::string_view what) {
  if (n > remaining()) {
    fail("unexpected end of file in " + std::string(what) + " (needs " + std::to_string(n) +
         " bytes, " + std::to_string(remaining()) + " left)");
  }
  const char* p = data_.data() + pos_;
  pos_ += n;
  return p;
}

std::int32_t ByteReader::i32(std::string_view what) {
  return load<std::int32_t>(take(4, what), swap_);
}
std::uint32_t ByteReader::u32(std::string_view what) {
  return load<std::uint32_t>(take(4, what), swap_);
}
std::int64_t ByteReader::i64(std::string_view what) {
  return load<std::int64_t>(take(8, what), swap_);
}
std::uint64_t ByteReader::u64(std::string_view what) {
  return load<std::uint64_t>(take(8, what), swap_);
}
float ByteReader::f32(std::string_view what) { return load<float>(take(4, what), swap_); }
double ByteReader::f64(std::string_view what) { return load<double>(take(8, what), swap_); }

double ByteReader::finite_f64(std::string_view what) {
  const std::size_t at = pos_;
  const double v = f64(what);
  if (!std::isfinite(v)) fail_at(at, std::string(what) + " is not a finite number");
  return v;
}

double ByteReader::finite_f32(std::string_view what) {
  const std::size_t at = pos_;
  const float v = f32(what);
  if (!std::isfinite(v)) fail_at(at, std::string(what) + " is not a finite number");
  return v;
}

std::string_view ByteReader::bytes(std::size_t n, std::string_view what) {
  return std::string_view(take(n, what), n);
}

void ByteReader::need(std::uint64_t count, std::uint64_t record_bytes, std::string_view what,
                      std::size_t at) const {
  const std::uint64_t left = remaining();
  if (record_bytes == 0 || count <= left / record_bytes) return;
  const std::string bytes =
      count > UINT64_MAX / record_bytes ? "more than 2^64" : std::to_string(count * record_bytes);
  fail_at(at == kHere ? pos_ : at, std::string(what) + " " + std::to_string(count) + " needs " +
                                       bytes + " bytes, the file has " + std::to_string(left) +
                                       " left");
}

}  // namespace conica::io::detail
