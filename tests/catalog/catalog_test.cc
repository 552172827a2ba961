// The catalogue's behaviour, the same suite on SQLite and on PostgreSQL (a server of its own,
// tests/support/postgres_server.h): first-run seeding, lookups, garment versions that never
// overwrite, a writer killed mid-save, readers beside a writer.

#include "catalog/catalog.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <thread>

#include "catalog/fabric_presets.h"
#include "sim_core/common/input_error.h"
#include "tests/support/postgres_server.h"

namespace costume::catalog {
namespace {

/// "v<n>". Built by appending: GCC 12 warns falsely (-Wrestrict) on "v" + std::to_string(n).
std::string VersionLabel(int n) {
  std::string label = "v";
  label += std::to_string(n);
  return label;
}

enum class Backend { kSqlite, kPostgres };

/// Bytes whose content is a function of (version, size) alone, with both in a header, so a
/// reader can tell a whole blob from a torn or mixed one.
std::vector<std::uint8_t> PatternBlob(int version, std::size_t size) {
  std::vector<std::uint8_t> bytes(size);
  const std::uint64_t header[2] = {static_cast<std::uint64_t>(version), size};
  std::memcpy(bytes.data(), header, sizeof header);
  for (std::size_t i = sizeof header; i < size; ++i) {
    bytes[i] = static_cast<std::uint8_t>(version * 31 + i * 7 + (i >> 12));
  }
  return bytes;
}

/// The version a pattern blob claims, or -1 when any byte disagrees with it.
int CheckPatternBlob(const std::vector<std::uint8_t>& bytes) {
  std::uint64_t header[2];
  if (bytes.size() < sizeof header) return -1;
  std::memcpy(header, bytes.data(), sizeof header);
  if (header[1] != bytes.size()) return -1;
  return PatternBlob(static_cast<int>(header[0]), bytes.size()) == bytes
             ? static_cast<int>(header[0])
             : -1;
}

class CatalogTest : public testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    if (GetParam() == Backend::kPostgres) {
      test::PostgresServer& server = test::PostgresServer::Shared();
      if (server.failed()) FAIL() << server.skip_reason();
      if (!server.skip_reason().empty()) GTEST_SKIP() << server.skip_reason();
      url_ = server.NewDatabaseUrl();
    } else {
      char pattern[] = "/tmp/catalog-test-XXXXXX";
      ASSERT_NE(mkdtemp(pattern), nullptr);
      dir_ = pattern;
      url_ = "sqlite:" + dir_ + "/catalog.sqlite";
    }
  }
  void TearDown() override {
    if (!dir_.empty()) std::filesystem::remove_all(dir_);
  }

  std::unique_ptr<Catalog> Open() { return Catalog::Open(url_); }

  std::int64_t Skirt(Catalog& catalog) { return catalog.Find(Kind::kGarment, "skirt")->id; }

  /// Forks a child that runs `body` on its own connection and exits 0 when it returns true.
  pid_t Fork(const std::function<bool(Catalog&)>& body) {
    const pid_t pid = fork();
    if (pid == 0) {
      bool ok = false;
      try {
        ok = body(*Catalog::Open(url_));
      } catch (const std::exception& error) {
        std::fprintf(stderr, "child %d: %s\n", getpid(), error.what());
      }
      _exit(ok ? 0 : 1);  // no destructors: the parent's objects are not the child's
    }
    return pid;
  }

  static int Wait(pid_t pid) {
    int status = 0;
    waitpid(pid, &status, 0);
    return status;
  }

  std::string url_;
  std::string dir_;
};

TEST_P(CatalogTest, SeedsTheBuiltInAssetsOnFirstRunOnly) {
  auto catalog = Open();
  EXPECT_EQ(catalog->schema_version(), 1);
  const auto avatars = catalog->List(Kind::kAvatar);
  ASSERT_EQ(avatars.size(), 1u);
  EXPECT_EQ(avatars[0].name, "humanoid");
  EXPECT_EQ(avatars[0].provenance, "built-in");
  EXPECT_EQ(avatars[0].licence, kBuiltInLicence);
  EXPECT_FALSE(avatars[0].fabric);

  const auto clips = catalog->List(Kind::kAnimation);
  std::map<std::string, std::string> categories;
  for (const EntryInfo& e : clips) categories[e.name] = e.category;
  const std::map<std::string, std::string> expected = {
      {"stand", "basic"}, {"walk", "basic"}, {"run", "basic"},
      {"jump", "basic"},  {"kick", "basic"}, {"dance", "choreography"}};
  EXPECT_EQ(categories, expected);

  const auto garments = catalog->List(Kind::kGarment);
  ASSERT_EQ(garments.size(), 3u);
  for (const EntryInfo& g : garments) {
    ASSERT_TRUE(g.fabric) << g.name;
    EXPECT_EQ(g.fabric->mass_per_area, BuiltInGarmentFabric().mass_per_area);
    EXPECT_EQ(g.fabric->bend_stiffness, BuiltInGarmentFabric().bend_stiffness);
    EXPECT_EQ(g.latest_version, 1);
    EXPECT_GT(g.created_utime, 1'600'000'000'000'000);  // after 2020, in µs
    const AssetData data = catalog->Data(g.id);
    EXPECT_EQ(data.format, "builtin");
    EXPECT_EQ(std::string(data.bytes.begin(), data.bytes.end()), g.name);
  }
  catalog.reset();
  auto again = Open();  // a second open finds the entries and seeds nothing
  EXPECT_EQ(again->List(Kind::kAnimation).size(), 6u);
  EXPECT_EQ(again->List(Kind::kGarment).size(), 3u);
  EXPECT_TRUE(again->CheckIntegrity().empty());
}

TEST_P(CatalogTest, FindsAndGetsEntries) {
  auto catalog = Open();
  const auto dance = catalog->Find(Kind::kAnimation, "dance");
  ASSERT_TRUE(dance);
  EXPECT_EQ(dance->category, "choreography");
  const EntryInfo same = catalog->Get(dance->id);
  EXPECT_EQ(same.name, "dance");
  EXPECT_EQ(same.kind, Kind::kAnimation);
  EXPECT_FALSE(catalog->Find(Kind::kGarment, "dance"));  // names are per kind
  EXPECT_FALSE(catalog->Find(Kind::kAnimation, "tango"));
  try {
    catalog->Get(987654);
    FAIL() << "no throw";
  } catch (const sim::InputError& error) {
    EXPECT_NE(std::string(error.what()).find("987654"), std::string::npos) << error.what();
  }
  EXPECT_TRUE(catalog->Thumbnail(dance->id).empty());  // opened without a thumbnail maker
}

TEST_P(CatalogTest, AddRefusesDuplicatesBadCategoriesAndGarmentsWithoutFabric) {
  auto catalog = Open();
  NewEntry clip;
  clip.kind = Kind::kAnimation;
  clip.name = "walk";
  clip.category = "basic";
  clip.data = {"bvh", {1, 2, 3}};
  EXPECT_THROW(catalog->Add(clip), sim::InputError);  // "walk" is seeded
  clip.name = "waltz";
  clip.category = "ballroom";
  EXPECT_THROW(catalog->Add(clip), sim::InputError);
  clip.category = "choreography";
  const std::int64_t id = catalog->Add(clip);
  EXPECT_EQ(catalog->Get(id).category, "choreography");
  NewEntry garment;
  garment.kind = Kind::kGarment;
  garment.name = "tunic";
  garment.data = {"builtin", {'s', 'k', 'i', 'r', 't'}};
  EXPECT_THROW(catalog->Add(garment), sim::InputError);
  // All or nothing: the second entry is refused, so the first is not added either.
  garment.fabric = FindFabricPreset("wool").fabric;
  NewEntry duplicate = garment;
  EXPECT_THROW(catalog->AddAll({garment, duplicate}), sim::InputError);
  EXPECT_FALSE(catalog->Find(Kind::kGarment, "tunic"));
}

// A name with a line break split `list`'s rows, and a pasted paragraph stood under a
// thumbnail: names and version labels are one short line.
TEST_P(CatalogTest, NamesAndLabelsAreOneShortLine) {
  auto catalog = Open();
  const auto refusal = [&](const NewEntry& entry) {
    try {
      catalog->Add(entry);
    } catch (const sim::InputError& error) {
      return std::string(error.what());
    }
    return std::string();
  };
  NewEntry clip;
  clip.kind = Kind::kAnimation;
  clip.category = "basic";
  clip.data = {"bvh", {1, 2, 3}};
  clip.name = "two\nlines";
  EXPECT_NE(refusal(clip).find("animation name 'two\\x0alines' (9 bytes) is not allowed: 1 to 200 "
                               "bytes without control characters"),
            std::string::npos)
      << refusal(clip);
  clip.name = std::string(201, 'x');
  EXPECT_NE(refusal(clip).find("(201 bytes) is not allowed"), std::string::npos);
  clip.name = std::string(200, 'x');
  EXPECT_EQ(refusal(clip), "");
  NewEntry garment;
  garment.kind = Kind::kGarment;
  garment.name = "tunic";
  garment.fabric = FindFabricPreset("wool").fabric;
  garment.data = {"builtin", {'s', 'k', 'i', 'r', 't'}};
  garment.version_label = "first\tcut";
  EXPECT_NE(refusal(garment).find("version label 'first\\x09cut'"), std::string::npos);
  const std::int64_t skirt = Skirt(*catalog);
  EXPECT_THROW(catalog->SaveGarmentVersion(skirt, {"edited-garment", PatternBlob(2, 64)},
                                           "a\rb", {}),
               sim::InputError);
  EXPECT_EQ(catalog->Get(skirt).latest_version, 1);
  EXPECT_EQ(catalog->SaveGarmentVersion(skirt, {"edited-garment", PatternBlob(2, 64)}, "", {}), 2);
}

TEST_P(CatalogTest, VersionsNeverOverwriteAndEveryVersionLoads) {
  auto catalog = Open();
  const std::int64_t skirt = Skirt(*catalog);
  const auto modified_before = catalog->Get(skirt).modified_utime;
  for (int v = 2; v <= 4; ++v) {
    const int saved =
        catalog->SaveGarmentVersion(skirt, {"edited-garment", PatternBlob(v, 1000 + v)},
                                    "edit " + std::to_string(v), {0x89, 'P', 'N', 'G'});
    EXPECT_EQ(saved, v);
  }
  const auto versions = catalog->Versions(skirt);
  ASSERT_EQ(versions.size(), 4u);
  EXPECT_EQ(versions[0].label, "initial");
  for (int v = 2; v <= 4; ++v) {
    EXPECT_EQ(versions[v - 1].version, v);
    EXPECT_EQ(versions[v - 1].label, "edit " + std::to_string(v));
    EXPECT_EQ(CheckPatternBlob(catalog->Data(skirt, v).bytes), v);
  }
  EXPECT_EQ(catalog->Data(skirt, 1).format, "builtin");  // version 1 untouched
  EXPECT_EQ(CheckPatternBlob(catalog->Data(skirt).bytes), 4);
  EXPECT_EQ(catalog->Get(skirt).latest_version, 4);
  EXPECT_GE(catalog->Get(skirt).modified_utime, modified_before);
  EXPECT_EQ(catalog->Thumbnail(skirt).size(), 4u);
  EXPECT_THROW(catalog->Data(skirt, 5), sim::InputError);
  const std::int64_t walk = catalog->Find(Kind::kAnimation, "walk")->id;
  EXPECT_THROW(catalog->SaveGarmentVersion(walk, {"bvh", {1}}, "", {}), sim::InputError);
  EXPECT_THROW(catalog->Versions(walk), sim::InputError);
  EXPECT_THROW(catalog->SaveGarmentVersion(skirt, {"edited-garment", {}}, "", {}), sim::InputError);
  EXPECT_TRUE(catalog->CheckIntegrity().empty());
}

// Remove takes an entry with every version, thumbnail and fabric, and nothing else; built-in
// entries stay.
TEST_P(CatalogTest, RemoveTakesAnEntryWithItsVersionsAndKeepsBuiltIns) {
  auto catalog = Open();
  NewEntry apron;
  apron.kind = Kind::kGarment;
  apron.name = "apron";
  apron.fabric = FabricParameters{};
  apron.data = {"edited-garment", PatternBlob(1, 64)};
  apron.thumbnail_png = {0x89, 'P', 'N', 'G'};
  const std::int64_t id = catalog->Add(apron);
  catalog->SaveGarmentVersion(id, {"edited-garment", PatternBlob(2, 64)}, "edit", {1, 2});
  const std::size_t garments = catalog->List(Kind::kGarment).size();

  const EntryInfo removed = catalog->Remove(id);
  EXPECT_EQ(removed.name, "apron");
  EXPECT_EQ(removed.latest_version, 2);
  EXPECT_FALSE(catalog->Find(Kind::kGarment, "apron"));
  EXPECT_THROW(catalog->Get(id), sim::InputError);
  EXPECT_THROW(catalog->Data(id, 1), sim::InputError);
  EXPECT_EQ(catalog->List(Kind::kGarment).size(), garments - 1);
  EXPECT_TRUE(catalog->CheckIntegrity().empty());
  EXPECT_THROW(catalog->Remove(id), sim::InputError);  // gone already

  try {
    catalog->Remove(Skirt(*catalog));
    FAIL() << "a built-in entry was removed";
  } catch (const sim::InputError& error) {
    EXPECT_NE(std::string(error.what()).find("'skirt'"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("built in"), std::string::npos) << error.what();
  }
  EXPECT_EQ(catalog->Versions(Skirt(*catalog)).size(), 1u);
  // The name is free again: the same garment imports anew as version 1.
  EXPECT_EQ(catalog->Get(catalog->Add(apron)).latest_version, 1);
}

TEST_P(CatalogTest, FabricIsSetAndValidated) {
  auto catalog = Open();
  const std::int64_t skirt = Skirt(*catalog);
  const FabricParameters silk = FindFabricPreset("silk").fabric;
  catalog->SetFabric(skirt, silk);
  const FabricParameters stored = *catalog->Get(skirt).fabric;
  EXPECT_EQ(stored.mass_per_area, silk.mass_per_area);  // doubles stored exactly
  EXPECT_EQ(stored.stretch_stiffness, silk.stretch_stiffness);
  EXPECT_EQ(stored.shear_stiffness, silk.shear_stiffness);
  EXPECT_EQ(stored.bend_stiffness, silk.bend_stiffness);
  EXPECT_EQ(stored.damping, silk.damping);
  EXPECT_EQ(stored.friction, silk.friction);
  FabricParameters bad = silk;
  bad.mass_per_area = -1.0;
  try {
    catalog->SetFabric(skirt, bad);
    FAIL() << "no throw";
  } catch (const sim::InputError& error) {
    EXPECT_NE(std::string(error.what()).find("mass_per_area"), std::string::npos) << error.what();
  }
  EXPECT_EQ(catalog->Get(skirt).fabric->mass_per_area, silk.mass_per_area);
  EXPECT_THROW(catalog->SetFabric(catalog->Find(Kind::kAvatar, "humanoid")->id, silk),
               sim::InputError);
}

// A writer saving large versions is killed (SIGKILL) at varying moments, most of them while
// a save is under way; afterwards every committed version is whole, the one being saved is
// either whole or absent, and the database is consistent.
TEST_P(CatalogTest, AWriterKilledMidSaveLeavesThePreviousVersionIntact) {
  const std::int64_t skirt = Skirt(*Open());
  constexpr std::size_t kSize = 6 << 20;  // a save takes long enough to be caught midway
  for (int round = 0; round < 4; ++round) {
    int ready[2];
    ASSERT_EQ(pipe(ready), 0);
    const pid_t writer = Fork([&](Catalog& catalog) {
      close(ready[0]);
      for (int i = 0;; ++i) {
        const int next = catalog.Get(skirt).latest_version + 1;
        const auto blob = PatternBlob(next, kSize + i);
        const char go = 1;
        if (write(ready[1], &go, 1) != 1) return false;  // "a save starts now"
        catalog.SaveGarmentVersion(skirt, {"edited-garment", blob}, VersionLabel(next), {});
      }
    });
    close(ready[1]);
    char go = 0;
    // Let one or two saves complete, then kill during the next, after a delay that varies
    // with the round so the kill lands at different points of the save.
    for (int starts = 0; starts < 2 + round % 2; ++starts) ASSERT_EQ(read(ready[0], &go, 1), 1);
    std::this_thread::sleep_for(std::chrono::milliseconds(3 * round));
    kill(writer, SIGKILL);
    const int status = Wait(writer);
    close(ready[0]);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "round " << round;
  }
  auto catalog = Open();  // a fresh connection
  EXPECT_EQ(catalog->CheckIntegrity(), std::vector<std::string>{});
  const auto versions = catalog->Versions(skirt);
  const int latest = catalog->Get(skirt).latest_version;
  ASSERT_EQ(static_cast<int>(versions.size()), latest);
  EXPECT_GE(latest, 5);                            // at least one save completed per round
  RecordProperty("versions_after_kills", latest);  // 7 when every kill landed mid-save
  for (int v = 2; v <= latest; ++v) {
    EXPECT_EQ(versions[v - 1].version, v);
    EXPECT_EQ(versions[v - 1].label, VersionLabel(v));
    EXPECT_EQ(CheckPatternBlob(catalog->Data(skirt, v).bytes), v) << "version " << v;
  }
  // The catalogue still takes saves after the kills (no lock left behind).
  EXPECT_EQ(catalog->SaveGarmentVersion(skirt, {"edited-garment", PatternBlob(latest + 1, 64)},
                                        "after", {}),
            latest + 1);
}

// One process saves versions while two others read; a reader checks every blob it sees is
// whole and belongs to the version the catalogue says, and that versions only grow.
TEST_P(CatalogTest, ReadersBesideAWriterSeeConsistentData) {
  const std::int64_t skirt = Skirt(*Open());
  constexpr int kVersions = 12;
  const pid_t writer = Fork([&](Catalog& catalog) {
    for (int v = 2; v <= kVersions + 1; ++v) {
      catalog.SaveGarmentVersion(skirt, {"edited-garment", PatternBlob(v, (1 << 20) + 977 * v)},
                                 VersionLabel(v), {});
    }
    return true;
  });
  auto reader = [&](Catalog& catalog) {
    int seen = 1;
    for (int i = 0; seen < kVersions + 1 && i < 100000; ++i) {
      const AssetData latest = catalog.Data(skirt);
      const int version = latest.format == "builtin" ? 1 : CheckPatternBlob(latest.bytes);
      if (version < 0 || version < seen) {
        std::fprintf(stderr, "reader saw version %d after %d\n", version, seen);
        return false;
      }
      seen = version;
      const auto versions = catalog.Versions(skirt);
      for (std::size_t k = 0; k < versions.size(); ++k) {
        if (versions[k].version != static_cast<int>(k) + 1) return false;
      }
      if (static_cast<int>(versions.size()) < seen) return false;
      if (version > 1 && CheckPatternBlob(catalog.Data(skirt, version).bytes) != version) {
        return false;
      }
    }
    return true;
  };
  const pid_t reader1 = Fork(reader);
  const pid_t reader2 = Fork(reader);
  const int writer_status = Wait(writer);
  EXPECT_TRUE(WIFEXITED(writer_status) && WEXITSTATUS(writer_status) == 0);
  for (pid_t r : {reader1, reader2}) {
    const int status = Wait(r);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "a reader saw torn data";
  }
  auto catalog = Open();
  EXPECT_EQ(catalog->Get(skirt).latest_version, kVersions + 1);
  EXPECT_TRUE(catalog->CheckIntegrity().empty());
}

// Two processes opening an empty catalogue at once seed it once.
TEST_P(CatalogTest, ConcurrentFirstOpensSeedOnce) {
  const pid_t a = Fork([](Catalog&) { return true; });
  const pid_t b = Fork([](Catalog&) { return true; });
  EXPECT_EQ(Wait(a), 0);
  EXPECT_EQ(Wait(b), 0);
  auto catalog = Open();
  EXPECT_EQ(catalog->List(Kind::kAnimation).size(), 6u);
  EXPECT_EQ(catalog->List(Kind::kGarment).size(), 3u);
}

INSTANTIATE_TEST_SUITE_P(Backends, CatalogTest,
                         testing::Values(Backend::kSqlite, Backend::kPostgres),
                         [](const testing::TestParamInfo<Backend>& param) {
                           return param.param == Backend::kSqlite ? "Sqlite" : "Postgres";
                         });

// ---- URLs --------------------------------------------------------------------------------

/// The message of the InputError `open` throws (empty when it throws none).
std::string OpenError(const std::string& url) {
  try {
    Catalog::Open(url);
  } catch (const sim::InputError& error) {
    return error.what();
  }
  return "";
}

TEST(CatalogUrl, ErrorsNameTheUrl) {
  char pattern[] = "/tmp/catalog-url-XXXXXX";
  ASSERT_NE(mkdtemp(pattern), nullptr);
  const std::string dir = pattern;
  { std::ofstream(dir + "/text.sqlite") << "this is not a database, just some text to read\n"; }
  const std::vector<std::string> urls = {
      "sqlite:" + dir + "/text.sqlite",           // not a database
      dir,                                        // a folder
      "mysql://localhost/catalog",                // unknown scheme
      "postgresql://nobody@127.0.0.1:1/catalog",  // nothing listens on port 1
  };
  for (const std::string& url : urls) {
    const std::string message = OpenError(url);
    EXPECT_NE(message.find(url), std::string::npos) << url << " → " << message;
  }
  EXPECT_NE(OpenError("").find("empty"), std::string::npos);
  const std::string secret = OpenError("postgresql://ada:s3cret@127.0.0.1:1/catalog");
  EXPECT_EQ(secret.find("s3cret"), std::string::npos) << secret;
  EXPECT_NE(secret.find("postgresql://ada:***@127.0.0.1:1/catalog"), std::string::npos) << secret;
  std::filesystem::remove_all(dir);
}

TEST(CatalogUrl, DefaultFollowsTheEnvironment) {
  setenv("COSTUME_CATALOG", "postgresql://team@db/costumes", 1);
  EXPECT_EQ(DefaultCatalogUrl(), "postgresql://team@db/costumes");
  unsetenv("COSTUME_CATALOG");
  setenv("XDG_DATA_HOME", "/data/home", 1);
  EXPECT_EQ(DefaultCatalogUrl(), "sqlite:/data/home/costume-designer/catalog.sqlite");
  unsetenv("XDG_DATA_HOME");
  setenv("HOME", "/home/ada", 1);
  EXPECT_EQ(DefaultCatalogUrl(), "sqlite:/home/ada/.local/share/costume-designer/catalog.sqlite");
}

TEST(CatalogUrl, SqliteUrlFormsOpenTheSameFile) {
  char pattern[] = "/tmp/catalog-url-XXXXXX";
  ASSERT_NE(mkdtemp(pattern), nullptr);
  const std::string path = std::string(pattern) + "/sub/c.sqlite";  // folder created
  Catalog::Open("sqlite:" + path)
      ->SetFabric(Catalog::Open(path)->Find(Kind::kGarment, "cape")->id,
                  FindFabricPreset("denim").fabric);
  EXPECT_EQ(Catalog::Open("sqlite://" + path)->Find(Kind::kGarment, "cape")->fabric->mass_per_area,
            FindFabricPreset("denim").fabric.mass_per_area);
  std::filesystem::remove_all(pattern);
}

}  // namespace
}  // namespace costume::catalog
