#include "io/text_reader.h"

#include <charconv>
#include <cmath>

namespace conica::io::detail {

namespace {

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

}  // namespace

bool Fields::next(std::string_view* field) {
  std::size_t i = 0;
  while (i < rest_.size() && is_blank(rest_[i])) ++i;
  if (i == rest_.size()) {
    rest_ = {};
    return false;
  }
  std::size_t j = i;
  while (j < rest_.size() && !is_blank(rest_[j])) ++j;
  *field = rest_.substr(i, j - i);
  rest_ = rest_.substr(j);
  return true;
}

std::string_view Fields::rest() const {
  std::size_t i = 0;
  while (i < rest_.size() && is_blank(rest_[i])) ++i;
  return rest_.substr(i);
}

bool LineReader::next(std::string_view* line) {
  if (pos_ >= text_.size()) return false;
  const std::size_t end = text_.find('\n', pos_);
  const std::size_t stop = end == std::string_view::npos ? text_.size() : end;
  std::string_view l = text_.substr(pos_, stop - pos_);
  if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
  pos_ = end == std::string_view::npos ? text_.size() : end + 1;
  ++line_;
  *line = l;
  return true;
}

bool LineReader::next_nonblank(std::string_view* line) {
  while (next(line)) {
    if (!Fields(*line).rest().empty()) return true;
  }
  return false;
}

std::string_view LineReader::expect_line(std::string_view what) {
  std::string_view line;
  if (!next_nonblank(&line)) fail("unexpected end of file, expected " + std::string(what));
  return line;
}

std::string LineReader::message_at(int line, std::string_view what) const {
  return name_ + ":" + std::to_string(line < 1 ? 1 : line) + ": " + std::string(what);
}

void LineReader::fail(std::string_view what) const { throw ParseError{message(what)}; }

void LineReader::fail_at(int line, std::string_view what) const {
  throw ParseError{message_at(line, what)};
}

bool TokenReader::next(std::string_view* token) {
  while (!fields_.next(token)) {
    std::string_view line;
    if (!lines_->next(&line)) return false;
    fields_ = Fields(line);
  }
  return true;
}

std::string_view TokenReader::expect(std::string_view what) {
  std::string_view token;
  if (!next(&token)) lines_->fail("unexpected end of file, expected " + std::string(what));
  return token;
}

bool parse_int(std::string_view token, std::int64_t* value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, *value);
  return !token.empty() && ec == std::errc() && ptr == end;
}

bool parse_double(std::string_view token, double* value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, *value);
  return !token.empty() && ec == std::errc() && ptr == end && std::isfinite(*value);
}

std::int64_t to_int(const LineReader& in, std::string_view token, std::string_view what) {
  std::int64_t v = 0;
  if (!parse_int(token, &v)) {
    in.fail(std::string(what) + ": '" + std::string(token) + "' is not an integer");
  }
  return v;
}

double to_double(const LineReader& in, std::string_view token, std::string_view what) {
  double v = 0;
  if (!parse_double(token, &v)) {
    in.fail(std::string(what) + ": '" + std::string(token) + "' is not a finite number");
  }
  return v;
}

std::int64_t to_count(const LineReader& in, std::string_view token, std::string_view what,
                      std::int64_t max_count) {
  const std::int64_t n = to_int(in, token, what);
  if (n < 0) in.fail(std::string(what) + " is negative (" + std::to_string(n) + ")");
  if (n > max_count) {
    in.fail(std::string(what) + " " + std::to_string(n) + " is more than the rest of the file " +
            "can hold (at most " + std::to_string(max_count) + ")");
  }
  return n;
}

std::int64_t int_field(const LineReader& in, Fields* f, std::string_view what) {
  std::string_view token;
  if (!f->next(&token)) in.fail("missing " + std::string(what));
  return to_int(in, token, what);
}

double double_field(const LineReader& in, Fields* f, std::string_view what) {
  std::string_view token;
  if (!f->next(&token)) in.fail("missing " + std::string(what));
  return to_double(in, token, what);
}

std::int64_t count_field(const LineReader& in, Fields* f, std::string_view what,
                         std::int64_t max_count) {
  std::string_view token;
  if (!f->next(&token)) in.fail("missing " + std::string(what));
  return to_count(in, token, what, max_count);
}

}  // namespace conica::io::detail
