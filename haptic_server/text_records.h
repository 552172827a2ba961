#pragma once
/// @file
/// The whitespace-separated numeric text format shared by trajectory files and device logs:
/// one record per line, '#' starts a comment, blank lines are skipped, every record has the
/// same named fields. Errors name the source, the line, the field, the value and the rule.

#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace costume::haptics {

/// Calls `record(line_number, values)` for each record of `text`, values parsed as doubles in
/// the order of `fields`. Throws costume::sim::InputError ("<source>:<line>: ...") for a record
/// with the wrong number of fields (listing the expected ones), a field that is not a number,
/// or a non-finite number. Exceptions thrown by `record` pass through.
void ParseRecords(std::string_view text, const std::string& source,
                  const std::vector<std::string>& fields,
                  const std::function<void(int line, const std::vector<double>& values)>& record);

/// "<source>:<line>: field '<field>' = <value> " — the common prefix of record errors.
std::string RecordErrorPrefix(const std::string& source, int line, const std::string& field,
                              double value);

/// Throws InputError (RecordErrorPrefix, then "m is not allowed: ...") unless the three
/// position fields x, y, z, at values[first] onwards, each lie within ±`limit` [m].
void RequirePositionWithin(const std::string& source, int line, const std::vector<double>& values,
                           int first, double limit);

/// The whole file at `path`; throws InputError naming the path when it cannot be read.
std::string ReadTextFile(const std::string& path, const std::string& what);

}  // namespace costume::haptics
