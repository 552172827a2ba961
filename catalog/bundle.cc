#include "catalog/bundle.h"

#include <set>

#include "sim_core/common/input_error.h"

namespace costume::catalog {

namespace {

const std::string kHeader = "COSTUME-BUNDLE 1\n";

bool IsPlainName(const std::string& name) {
  return !name.empty() && name != "." && name != ".." &&
         name.find_first_of("/\\\n") == std::string::npos && name.size() <= 255;
}

}  // namespace

bool IsBundle(const std::vector<std::uint8_t>& bytes) {
  return bytes.size() >= kHeader.size() &&
         std::equal(kHeader.begin(), kHeader.end(), bytes.begin());
}

std::vector<std::uint8_t> PackBundle(const std::vector<BundleFile>& files) {
  std::vector<std::uint8_t> out(kHeader.begin(), kHeader.end());
  std::set<std::string> names;
  for (const BundleFile& file : files) {
    if (!IsPlainName(file.name) || !names.insert(file.name).second) {
      throw sim::InputError("bundle: file name '" + sim::QuoteForMessage(file.name) +
                            "' must be a plain, unique file name");
    }
    const std::string head = file.name + "\n" + std::to_string(file.bytes.size()) + "\n";
    out.insert(out.end(), head.begin(), head.end());
    out.insert(out.end(), file.bytes.begin(), file.bytes.end());
    out.push_back('\n');
  }
  return out;
}

std::vector<BundleFile> UnpackBundle(const std::vector<std::uint8_t>& bytes,
                                     const std::string& source) {
  auto fail = [&source](const std::string& what) -> void {
    throw sim::InputError(source + ": malformed bundle: " + what);
  };
  if (!IsBundle(bytes)) fail("it does not start with \"COSTUME-BUNDLE 1\"");
  std::size_t at = kHeader.size();
  auto line = [&]() {
    std::string text;
    while (at < bytes.size() && bytes[at] != '\n') text.push_back(static_cast<char>(bytes[at++]));
    if (at >= bytes.size()) fail("truncated header");
    ++at;
    return text;
  };
  std::vector<BundleFile> files;
  std::set<std::string> names;
  while (at < bytes.size()) {
    BundleFile file;
    file.name = line();
    if (!IsPlainName(file.name) || !names.insert(file.name).second) {
      fail("file name '" + sim::QuoteForMessage(file.name) + "' is not a plain, unique file name");
    }
    const std::string shown = "file '" + sim::QuoteForMessage(file.name, 255) + "'";
    const std::string size_text = line();
    if (size_text.empty() || size_text.size() > 12 ||
        size_text.find_first_not_of("0123456789") != std::string::npos) {
      fail(shown + ": size '" + sim::QuoteForMessage(size_text) + "' is not a number");
    }
    const std::size_t size = std::stoull(size_text);
    if (size + 1 > bytes.size() - at) fail(shown + " is truncated");
    file.bytes.assign(bytes.begin() + at, bytes.begin() + at + size);
    at += size;
    if (bytes[at++] != '\n') fail(shown + " is not followed by a newline");
    files.push_back(std::move(file));
  }
  return files;
}

}  // namespace costume::catalog
