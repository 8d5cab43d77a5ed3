#pragma once
// IsError: a gtest predicate for absl::Status results, shared by the server's unit tests.
#include <gtest/gtest.h>

#include <initializer_list>
#include <string>
#include <string_view>

#include "absl/status/status.h"

namespace tessera::test {

// OK when `status` has `code`, its message contains every one of `needles` and none of
// `secrets` (e.g. a token that must never reach an error message).
inline ::testing::AssertionResult IsError(const absl::Status& status, absl::StatusCode code,
                                          std::initializer_list<std::string_view> needles,
                                          std::initializer_list<std::string_view> secrets = {}) {
  if (status.code() != code)
    return ::testing::AssertionFailure()
           << "code " << absl::StatusCodeToString(status.code()) << ", want "
           << absl::StatusCodeToString(code) << " (" << status << ")";
  const std::string message(status.message());
  for (std::string_view needle : needles) {
    if (message.find(needle) == std::string::npos)
      return ::testing::AssertionFailure()
             << "message \"" << message << "\" does not name \"" << needle << "\"";
  }
  for (std::string_view secret : secrets) {
    if (message.find(secret) != std::string::npos)
      return ::testing::AssertionFailure() << "message \"" << message << "\" leaks a secret";
  }
  return ::testing::AssertionSuccess();
}

}  // namespace tessera::test
