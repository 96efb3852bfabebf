// Internal to conica_io: line and token reading of text mesh files with the position kept,
// so that every error can say "file:line: what is wrong".
//
// Parsers report a malformed file by throwing ParseError; parse_mesh() turns it into a
// Result, so no exception leaves the library.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace conica::io::detail {

// A complete "file:line: what" message.
struct ParseError {
  std::string message;
};

// Splits one line on blanks (space, tab).
class Fields {
 public:
  explicit Fields(std::string_view line) : rest_(line) {}
  // The next field; false when the line has no more.
  bool next(std::string_view* field);
  // What is left of the line with leading blanks removed.
  std::string_view rest() const;

 private:
  std::string_view rest_;
};

// Reads a text buffer line by line. CR before LF is dropped.
class LineReader {
 public:
  LineReader(std::string_view text, std::string name) : text_(text), name_(std::move(name)) {}

  // Next line without its end of line; false at end of file.
  bool next(std::string_view* line);
  // Next line that is not blank; false at end of file.
  bool next_nonblank(std::string_view* line);
  // Next non-blank line; throws "unexpected end of file, expected <what>" at end of file.
  std::string_view expect_line(std::string_view what);

  // 1-based number of the line last returned (0 before the first).
  int line_number() const { return line_; }
  // Bytes not read yet: an upper bound on what the rest of the file can hold.
  std::size_t remaining_bytes() const { return text_.size() - pos_; }
  const std::string& name() const { return name_; }

  // "name:line: what" for the line last returned (line 1 before the first).
  std::string message(std::string_view what) const { return message_at(line_, what); }
  std::string message_at(int line, std::string_view what) const;
  [[noreturn]] void fail(std::string_view what) const;
  [[noreturn]] void fail_at(int line, std::string_view what) const;

 private:
  std::string_view text_;
  std::string name_;
  std::size_t pos_ = 0;
  int line_ = 0;
};

// Reads blank-separated tokens across lines (VTK legacy is free format).
class TokenReader {
 public:
  explicit TokenReader(LineReader* lines) : lines_(lines) {}
  // Next token; false at end of file.
  bool next(std::string_view* token);
  // Next token; throws "unexpected end of file, expected <what>" at end of file.
  std::string_view expect(std::string_view what);
  // Drops the rest of the current line.
  void skip_line() { fields_ = Fields({}); }
  // Line of the token last returned.
  int line_number() const { return lines_->line_number(); }
  LineReader& lines() { return *lines_; }

 private:
  LineReader* lines_;
  Fields fields_{{}};
};

// Whole-token number parsing; false if the token is not exactly one number.
bool parse_int(std::string_view token, std::int64_t* value);
bool parse_double(std::string_view token, double* value);  // accepts only finite values

// Throwing variants: "<what>: '<token>' is not an integer / a finite number".
std::int64_t to_int(const LineReader& in, std::string_view token, std::string_view what);
double to_double(const LineReader& in, std::string_view token, std::string_view what);
// A count in [0, max_count]; a count above what the rest of the file can hold is an error
// (a header that claims 10^12 nodes must not allocate for them).
std::int64_t to_count(const LineReader& in, std::string_view token, std::string_view what,
                      std::int64_t max_count);

// Next field of a line as an integer / finite number; throws if missing or malformed.
std::int64_t int_field(const LineReader& in, Fields* f, std::string_view what);
double double_field(const LineReader& in, Fields* f, std::string_view what);
std::int64_t count_field(const LineReader& in, Fields* f, std::string_view what,
                         std::int64_t max_count);

}  // namespace conica::io::detail
