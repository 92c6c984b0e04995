// Typed exceptions of the library. Library code never aborts on user input: it throws one of
// these, with a message that names the likely cause.
#pragma once

#include <stdexcept>
#include <string>

namespace moslam {

// Base of every moslam exception.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The input (a file, a factor, an options struct) is malformed or out of range.
class InvalidInputError : public Error {
 public:
  using Error::Error;
};

// The problem cannot be solved as posed: disconnected graph, missing anchor, singular system.
class UnderdeterminedError : public Error {
 public:
  using Error::Error;
};

// A computation produced NaN/Inf or a factorisation failed for numerical reasons.
class NumericalError : public Error {
 public:
  using Error::Error;
};

}  // namespace moslam
