// A value or the reason there is none: what every reader returns instead of throwing.
#pragma once

#include <string>
#include <utility>
#include <variant>

namespace conica::io {

// Why an operation failed, for a human: "liver.msh:412: element 37 references unknown node 9001".
struct Error {
  std::string message;
};

// Either a T or an Error (a small std::expected until we move to C++23).
template <class T>
class Result {
 public:
  Result(T value) : v_(std::move(value)) {}      // NOLINT: implicit by design
  Result(Error error) : v_(std::move(error)) {}  // NOLINT: implicit by design

  bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }

  // Precondition: ok().
  const T& value() const& { return std::get<0>(v_); }
  T& value() & { return std::get<0>(v_); }
  T&& value() && { return std::get<0>(std::move(v_)); }

  // Precondition: !ok().
  const std::string& error() const { return std::get<1>(v_).message; }

 private:
  std::variant<T, Error> v_;
};

}  // namespace conica::io
