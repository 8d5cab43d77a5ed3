#pragma once
// RETURN_IF_ERROR and ASSIGN_OR_RETURN: early returns on an absl::Status / absl::StatusOr
// error, instead of hand-written `if (!st.ok()) return st;` checks.
//
//   RETURN_IF_ERROR(Upload(buffer));
//   ASSIGN_OR_RETURN(vk::Image image, vk::Image::Create(ctx, desc));
//   ASSIGN_OR_RETURN(auto* state, Exposure(scene, view));
//
// Both work in functions returning absl::Status or any absl::StatusOr<T>.
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

#define TESSERA_STATUS_CONCAT_INNER(a, b) a##b
#define TESSERA_STATUS_CONCAT(a, b) TESSERA_STATUS_CONCAT_INNER(a, b)

// Evaluates `expr` (an absl::Status) once; returns it from the enclosing function when not OK.
#define RETURN_IF_ERROR(expr)                                             \
  do {                                                                    \
    if (::absl::Status tessera_status_ = (expr); !tessera_status_.ok()) { \
      return tessera_status_;                                             \
    }                                                                     \
  } while (false)

// Evaluates `rexpr` (an absl::StatusOr<T>) once; returns its status when not OK, else moves
// its value into `lhs` (a declaration such as `auto x` or an existing lvalue).
#define ASSIGN_OR_RETURN(lhs, rexpr) \
  TESSERA_ASSIGN_OR_RETURN_IMPL(TESSERA_STATUS_CONCAT(tessera_statusor_, __LINE__), lhs, rexpr)

#define TESSERA_ASSIGN_OR_RETURN_IMPL(statusor, lhs, rexpr) \
  auto statusor = (rexpr);                                  \
  if (!statusor.ok()) return std::move(statusor).status();  \
  lhs = std::move(statusor).value()
