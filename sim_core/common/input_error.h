#pragma once
/// @file
/// The one error type thrown while loading, building and validating user input.
/// Hot paths (the solver step) never throw: they report trouble through StepReport flags.

#include <cstddef>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <string_view>

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

/// Several values as messages quote a vector or a tuple: each by FormatValue, between
/// `open` and `close` and separated by ", " ("(1, nan, 0)").
std::string FormatValues(std::initializer_list<double> values, const char* open = "(",
                         const char* close = ")");

/// `text` from a file or a user, as a message quotes it: at most `max_bytes` of it (never a
/// character cut in two), then "…" if there was more; control characters and bytes that are
/// not UTF-8 as \xNN (a damaged file's word "1.\xb497" says which byte is wrong, where the
/// raw byte would print as nothing or as the terminal's replacement mark).
std::string QuoteForMessage(std::string_view text, std::size_t max_bytes = 40);

/// Throws InputError unless `value` is finite and value > 0.
/// `field` names the offending field, e.g. "material.density".
void RequirePositive(const std::string& field, double value, const std::string& unit);

/// Throws InputError unless `value` is finite and value >= 0.
void RequireNonNegative(const std::string& field, double value, const std::string& unit);

/// Throws InputError unless `value` is finite and 0 < value <= hi.
void RequirePositiveAtMost(const std::string& field, double value, double hi,
                           const std::string& unit);

/// Throws InputError unless `value` is finite and lo <= value <= hi.
void RequireInRange(const std::string& field, double value, double lo, double hi,
                    const std::string& unit);

/// Throws InputError unless `value` is finite.
void RequireFinite(const std::string& field, double value, const std::string& unit);

/// Largest coordinate a position in a model may have [m]: a cloth particle's, a skin
/// vertex's (from the avatar's origin), a joint's rest offset (from its parent), a clip's
/// root translation (from the clip's origin). Far beyond any stage, and far below where
/// arithmetic fails: a clip whose root jumped 1e298 m for one frame (a damaged BVH) left the
/// cloth non-finite for good.
inline constexpr double kMaxCoordinate = 1e4;

}  // namespace costume::sim
