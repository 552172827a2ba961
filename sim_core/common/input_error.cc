#include "sim_core/common/input_error.h"

#include <charconv>
#include <cmath>

namespace costume::sim {

std::string FormatValue(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  char buffer[64];
  // Six significant digits: enough to recognise a value, short enough to read.
  auto result = std::to_chars(buffer, buffer + sizeof(buffer), value,
                              std::chars_format::general, 6);
  return std::string(buffer, result.ptr);
}

std::string FormatValues(std::initializer_list<double> values, const char* open,
                         const char* close) {
  std::string text = open;
  bool first = true;
  for (double value : values) {
    if (!first) text += ", ";
    text += FormatValue(value);
    first = false;
  }
  return text + close;
}

namespace {
std::string WithUnit(const std::string& text, const std::string& unit) {
  return unit.empty() ? text : text + " " + unit;
}
}  // namespace

void RequirePositive(const std::string& field, double value, const std::string& unit) {
  if (!(std::isfinite(value) && value > 0)) {
    throw InputError(field + " = " + WithUnit(FormatValue(value), unit) +
                     " is not allowed: it must be a finite number > 0");
  }
}

void RequireNonNegative(const std::string& field, double value, const std::string& unit) {
  if (!(std::isfinite(value) && value >= 0)) {
    throw InputError(field + " = " + WithUnit(FormatValue(value), unit) +
                     " is not allowed: it must be a finite number >= 0");
  }
}

void RequirePositiveAtMost(const std::string& field, double value, double hi,
                           const std::string& unit) {
  if (!(std::isfinite(value) && value > 0 && value <= hi)) {
    throw InputError(field + " = " + WithUnit(FormatValue(value), unit) +
                     " is out of range: allowed above 0 up to " + WithUnit(FormatValue(hi), unit));
  }
}

void RequireInRange(const std::string& field, double value, double lo, double hi,
                    const std::string& unit) {
  if (!(std::isfinite(value) && value >= lo && value <= hi)) {
    throw InputError(field + " = " + WithUnit(FormatValue(value), unit) +
                     " is out of range: allowed " + FormatValue(lo) + " to " +
                     WithUnit(FormatValue(hi), unit));
  }
}

void RequireFinite(const std::string& field, double value, const std::string& unit) {
  if (!std::isfinite(value)) {
    throw InputError(field + " = " + WithUnit(FormatValue(value), unit) +
                     " is not allowed: it must be a finite number");
  }
}

}  // namespace costume::sim
