#pragma once
/// @file
/// The message of the sim::InputError a call throws, for tests that check what a refusal
/// says (the file, field, value and allowed range).

#include <string>

#include "sim_core/common/input_error.h"

namespace costume::test {

/// What `call()` throws as sim::InputError, or "" when it returns. Other exceptions pass.
std::string RefusalOf(auto&& call) {
  try {
    call();
  } catch (const sim::InputError& error) {
    return error.what();
  }
  return "";
}

}  // namespace costume::test
