// Errors the user can cause are values, never exceptions across module boundaries and never
// crashes (DESIGN.md, Conventions). An Error carries a message and where it happened.
#pragma once

#include <cassert>
#include <string>
#include <utility>
#include <variant>

namespace feedloop {

// Where a user-visible input came from: a file (or channel) name, 1-based line and column.
// line/column 0 mean "unknown".
struct SourceLocation {
  std::string source;
  int line = 0;
  int column = 0;

  std::string to_string() const {
    std::string s = source.empty() ? std::string("<input>") : source;
    if (line > 0) s += ":" + std::to_string(line);
    if (column > 0) s += ":" + std::to_string(column);
    return s;
  }
};

struct Error {
  std::string message;
  SourceLocation where;

  // "file:line:col: message", or the bare message when the location is unknown.
  std::string to_string() const {
    if (where.source.empty() && where.line == 0) return message;
    return where.to_string() + ": " + message;
  }
};

// A value or an Error. Deliberately tiny (std::expected is C++23).
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}          // NOLINT(google-explicit-constructor)
  Result(Error error) : v_(std::move(error)) {}      // NOLINT(google-explicit-constructor)

  bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }

  T& value() & { assert(ok()); return std::get<0>(v_); }
  const T& value() const& { assert(ok()); return std::get<0>(v_); }
  T&& value() && { assert(ok()); return std::get<0>(std::move(v_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

  const Error& error() const { assert(!ok()); return std::get<1>(v_); }

 private:
  std::variant<T, Error> v_;
};

// Result<void>: success or an Error.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Error error) : error_(std::move(error)), ok_(false) {}  // NOLINT(google-explicit-constructor)
  static Status Ok() { return {}; }

  bool ok() const { return ok_; }
  explicit operator bool() const { return ok_; }
  const Error& error() const { assert(!ok_); return error_; }

 private:
  Error error_;
  bool ok_ = true;
};

}  // namespace feedloop
