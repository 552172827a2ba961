#include "sim_core/common/input_error.h"

#include <algorithm>
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

// Bytes of the UTF-8 character starting at text[i] that prints: 1-4, or 0 for a control
// character (C0, DEL, C1), a stray or overlong byte, a surrogate or a cut sequence.
std::size_t PrintableCharacterAt(std::string_view text, std::size_t i) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[k]); };
  const unsigned char lead = byte(i);
  if (lead < 0x80) return lead >= 0x20 && lead != 0x7f ? 1 : 0;
  std::size_t length = 0;
  unsigned char low = 0x80, high = 0xbf;  // allowed range of the second byte
  if (lead == 0xc2) {
    length = 2, low = 0xa0;  // U+0080-U+009F are C1 controls
  } else if (lead >= 0xc3 && lead <= 0xdf) {
    length = 2;
  } else if (lead >= 0xe0 && lead <= 0xef) {
    length = 3;
    if (lead == 0xe0) low = 0xa0;   // overlong
    if (lead == 0xed) high = 0x9f;  // surrogates
  } else if (lead >= 0xf0 && lead <= 0xf4) {
    length = 4;
    if (lead == 0xf0) low = 0x90;   // overlong
    if (lead == 0xf4) high = 0x8f;  // beyond U+10FFFF
  } else {
    return 0;
  }
  if (i + length > text.size() || byte(i + 1) < low || byte(i + 1) > high) return 0;
  for (std::size_t k = 2; k < length; ++k) {
    if (byte(i + k) < 0x80 || byte(i + k) > 0xbf) return 0;
  }
  return length;
}

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

std::string QuoteForMessage(std::string_view text, std::size_t max_bytes) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string shown;
  std::size_t i = 0;
  while (i < text.size()) {
    const std::size_t length = PrintableCharacterAt(text, i);
    if (i + std::max<std::size_t>(length, 1) > max_bytes) break;
    if (length > 0) {
      shown.append(text.substr(i, length));
      i += length;
    } else {
      const auto byte = static_cast<unsigned char>(text[i++]);
      shown += {'\\', 'x', kHex[byte >> 4], kHex[byte & 0xf]};
    }
  }
  if (i < text.size()) shown += "…";
  return shown;
}

}  // namespace costume::sim
