#pragma once
// The exception hierarchy. Every error incise reports to a user is one of these; the CLI
// prints what() as one line and exits with code 1.
#include <stdexcept>
#include <string>

namespace incise {

class Error : public std::runtime_error {
public:
  // Bytes of the message that are not UTF-8 (a binary file's token quoted in a parse error)
  // become \xNN: a terminal prints the message, Python gets it as str.
  explicit Error(const std::string& what);
  explicit Error(const char* what) : Error(std::string(what)) {}
};

// Malformed or unreadable file. what() is "FILE:LINE: reason" (LINE omitted when unknown).
class IoError : public Error {
public:
  // Out of line (mesh/errors.cpp): inlined, GCC 12 raises a false -Wrestrict (PR105329).
  IoError(const std::string& file, long line, const std::string& reason);
  const std::string& file() const { return file_; }
  long line() const { return line_; }

private:
  std::string file_;
  long line_;
};

// A mesh invariant does not hold (thrown by validate() and by edits given invalid input).
class InvalidMesh : public Error {
public:
  using Error::Error;
};

// An argument or option out of its domain.
class InvalidArgument : public Error {
public:
  using Error::Error;
};

} // namespace incise
