#pragma once
/// @file
/// The one error type thrown while loading, building and validating user input.
/// Hot paths (the solver step) never throw: they report trouble through StepReport flags.

#include <stdexcept>
#include <string>

namespace costume::sim {

/// Thrown for refused input: a bad file, field or value.
/// The message names where the problem is (file and line when known), the field, the value
/// found and the allowed range, so that a user can fix it without reading code.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

/// Formats a double the way error messages quote values: shortest round-trip form, and
/// "nan"/"inf" spelled out.
std::string FormatValue(double value);

/// Throws InputError unless `value` is finite and value > 0.
/// `field` names the offending field, e.g. "material.density".
void RequirePositive(const std::string& field, double value, const std::string& unit);

/// Throws InputError unless `value` is finite and value >= 0.
void RequireNonNegative(const std::string& field, double value, const std::string& unit);

/// Throws InputError unless `value` is finite and lo <= value <= hi.
void RequireInRange(const std::string& field, double value, double lo, double hi,
                    const std::string& unit);

/// Throws InputError unless `value` is finite.
void RequireFinite(const std::string& field, double value, const std::string& unit);

}  // namespace costume::sim
