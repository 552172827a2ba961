// A bundle keeps several files as one stored asset; a damaged one is refused with a message
// short enough to read, naming the stored entry.
#include "catalog/bundle.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "sim_core/common/input_error.h"
#include "tests/support/refusal.h"

namespace costume::catalog {
namespace {

std::vector<std::uint8_t> Bytes(const std::string& text) { return {text.begin(), text.end()}; }

/// What unpacking `bytes` as the stored garment 'suit' says.
std::string UnpackRefusal(const std::vector<std::uint8_t>& bytes) {
  return test::RefusalOf([&] { UnpackBundle(bytes, "garment 'suit'"); });
}

TEST(Bundle, UnpacksWhatItPacked) {
  const std::vector<BundleFile> files = {{"base.obj", Bytes("v 0 0 0\n")},
                                         {"empty.mhw", {}},
                                         {"line\nbreaks.txt", Bytes("\n\n")}};
  EXPECT_NE(test::RefusalOf([&] { PackBundle(files); })
                .find("file name 'line\\x0abreaks.txt' must be a plain, unique file name"),
            std::string::npos);
  const std::vector<BundleFile> plain(files.begin(), files.begin() + 2);
  const std::vector<BundleFile> back = UnpackBundle(PackBundle(plain), "test");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].name, "base.obj");
  EXPECT_EQ(back[0].bytes, Bytes("v 0 0 0\n"));
  EXPECT_EQ(back[1].name, "empty.mhw");
  EXPECT_TRUE(back[1].bytes.empty());
}

TEST(Bundle, ADamagedHeaderIsQuotedShortAndEscaped) {
  // The size line's newline lost: the size swallows the file's first kilobyte.
  const std::string size_lost =
      "COSTUME-BUNDLE 1\nbase.obj\n1025" + std::string(1024, '7') + "\n";
  std::string message = UnpackRefusal(Bytes(size_lost));
  EXPECT_EQ(message.rfind("garment 'suit': malformed bundle: file 'base.obj': size '", 0), 0u)
      << message;
  EXPECT_LT(message.size(), 150u) << message;
  // A name damaged into a control byte and a path.
  message = UnpackRefusal(Bytes("COSTUME-BUNDLE 1\nba\x01se/../x\n1\nv\n"));
  EXPECT_NE(message.find("file name 'ba\\x01se/../x' is not a plain"), std::string::npos)
      << message;
}

}  // namespace
}  // namespace costume::catalog
