#include "haptic_server/text_records.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "sim_core/common/input_error.h"

namespace costume::haptics {

namespace {

std::vector<std::string_view> SplitFields(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
    if (j > i) tokens.push_back(line.substr(i, j - i));
    i = j;
  }
  return tokens;
}

std::string JoinNames(const std::vector<std::string>& fields) {
  std::string joined;
  for (const std::string& f : fields) joined += (joined.empty() ? "" : " ") + f;
  return joined;
}

double ParseNumber(std::string_view token, const std::string& where, const std::string& field) {
  double value = 0.0;
  const char* end = token.data() + token.size();
  const auto result = std::from_chars(token.data(), end, value);
  if (result.ec != std::errc() || result.ptr != end) {
    throw sim::InputError(where + "field '" + field + "' = '" + std::string(token) +
                          "' is not a number");
  }
  if (!std::isfinite(value)) {
    throw sim::InputError(where + "field '" + field + "' = " + sim::FormatValue(value) +
                          " is not allowed: it must be a finite number");
  }
  return value;
}

}  // namespace

std::string RecordErrorPrefix(const std::string& source, int line, const std::string& field,
                              double value) {
  return source + ":" + std::to_string(line) + ": field '" + field + "' = " +
         sim::FormatValue(value) + " ";
}

void RequirePositionWithin(const std::string& source, int line, const std::vector<double>& values,
                           int first, double limit) {
  for (int i = 0; i < 3; ++i) {
    const double value = values[first + i];
    if (std::abs(value) <= limit) continue;
    throw sim::InputError(RecordErrorPrefix(source, line, std::string(1, "xyz"[i]), value) +
                          "m is not allowed: a device's tip lies within ±" +
                          sim::FormatValue(limit) + " m of its origin");
  }
}

void ParseRecords(std::string_view text, const std::string& source,
                  const std::vector<std::string>& fields,
                  const std::function<void(int line, const std::vector<double>& values)>& record) {
  std::vector<double> values(fields.size());
  int line_number = 0;
  std::size_t start = 0;
  while (start <= text.size()) {
    std::size_t stop = text.find('\n', start);
    if (stop == std::string_view::npos) stop = text.size();
    std::string_view line = text.substr(start, stop - start);
    start = stop + 1;
    ++line_number;
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) {
      line = line.substr(0, hash);
    }
    const std::vector<std::string_view> tokens = SplitFields(line);
    if (tokens.empty()) continue;
    const std::string where = source + ":" + std::to_string(line_number) + ": ";
    if (tokens.size() != fields.size()) {
      throw sim::InputError(where + "expected " + std::to_string(fields.size()) + " fields (" +
                            JoinNames(fields) + "), found " + std::to_string(tokens.size()));
    }
    for (std::size_t f = 0; f < fields.size(); ++f) {
      values[f] = ParseNumber(tokens[f], where, fields[f]);
    }
    record(line_number, values);
  }
}

std::string ReadTextFile(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw sim::InputError(what + " '" + path + "' cannot be opened for reading");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace costume::haptics
