#include "catalog/catalog.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <iostream>

#include "catalog/catalog_loader.h"
#include "catalog/fabric_presets.h"
#include "catalog/sql_connection.h"
#include "sim_core/avatar/garment_patterns.h"
#include "sim_core/avatar/procedural_clips.h"
#include "sim_core/common/input_error.h"

namespace costume::catalog {

namespace {

/// One schema migration: applied once, in order, recorded in schema_migrations.
/// "{id}" and "{blob}" stand for the dialect's auto-increment key and byte-string types.
struct Migration {
  int version;
  const char* description;
  const char* sql;
};

// Never edit a migration that has shipped: add the next one instead.
const Migration kMigrations[] = {
    {1, "entries, fabrics, versions",
     R"sql(
CREATE TABLE entries (
  id {id},
  kind TEXT NOT NULL CHECK (kind IN ('avatar', 'garment', 'animation')),
  name TEXT NOT NULL CHECK (name <> ''),
  category TEXT NOT NULL DEFAULT '',
  provenance TEXT NOT NULL DEFAULT '',
  licence TEXT NOT NULL DEFAULT '',
  created_utime BIGINT NOT NULL,
  modified_utime BIGINT NOT NULL,
  latest_version INTEGER NOT NULL DEFAULT 1 CHECK (latest_version >= 1),
  UNIQUE (kind, name)
);
CREATE TABLE fabrics (
  entry_id BIGINT PRIMARY KEY REFERENCES entries(id) ON DELETE CASCADE,
  mass_per_area DOUBLE PRECISION NOT NULL,
  stretch_stiffness DOUBLE PRECISION NOT NULL,
  shear_stiffness DOUBLE PRECISION NOT NULL,
  bend_stiffness DOUBLE PRECISION NOT NULL,
  damping DOUBLE PRECISION NOT NULL,
  friction DOUBLE PRECISION NOT NULL
);
CREATE TABLE versions (
  entry_id BIGINT NOT NULL REFERENCES entries(id) ON DELETE CASCADE,
  version INTEGER NOT NULL CHECK (version >= 1),
  label TEXT NOT NULL DEFAULT '',
  created_utime BIGINT NOT NULL,
  format TEXT NOT NULL CHECK (format <> ''),
  data {blob} NOT NULL,
  thumbnail {blob},
  PRIMARY KEY (entry_id, version)
);
)sql"},
};

std::string ForDialect(std::string sql, Dialect dialect) {
  auto replace = [&sql](const std::string& from, const std::string& to) {
    for (auto at = sql.find(from); at != std::string::npos; at = sql.find(from, at + to.size())) {
      sql.replace(at, from.size(), to);
    }
  };
  const bool sqlite = dialect == Dialect::kSqlite;
  replace("{id}", sqlite ? "INTEGER PRIMARY KEY AUTOINCREMENT" : "BIGSERIAL PRIMARY KEY");
  replace("{blob}", sqlite ? "BLOB" : "BYTEA");
  return sql;
}

/// "an " or "a ", for messages.
const char* Article(Kind kind) {
  return kind == Kind::kAvatar || kind == Kind::kAnimation ? "an " : "a ";
}

std::int64_t NowUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::int64_t AsInt(const SqlValue& v) {
  if (const auto* i = std::get_if<std::int64_t>(&v)) return *i;
  if (const auto* d = std::get_if<double>(&v)) return static_cast<std::int64_t>(*d);
  return 0;
}
double AsDouble(const SqlValue& v) {
  if (const auto* d = std::get_if<double>(&v)) return *d;
  if (const auto* i = std::get_if<std::int64_t>(&v)) return static_cast<double>(*i);
  return 0.0;
}
std::string AsText(const SqlValue& v) {
  if (const auto* s = std::get_if<std::string>(&v)) return *s;
  return {};
}
Blob AsBlob(const SqlValue& v) {
  if (const auto* b = std::get_if<Blob>(&v)) return *b;
  if (const auto* s = std::get_if<std::string>(&v)) return Blob(s->begin(), s->end());
  return {};
}

const char* const kEntryColumns =
    "SELECT e.id, e.kind, e.name, e.category, e.provenance, e.licence, e.created_utime, "
    "e.modified_utime, e.latest_version, f.mass_per_area, f.stretch_stiffness, "
    "f.shear_stiffness, f.bend_stiffness, f.damping, f.friction "
    "FROM entries e LEFT JOIN fabrics f ON f.entry_id = e.id ";

EntryInfo ToEntry(const SqlRow& row) {
  EntryInfo e;
  e.id = AsInt(row[0]);
  e.kind = ParseKind(AsText(row[1]));
  e.name = AsText(row[2]);
  e.category = AsText(row[3]);
  e.provenance = AsText(row[4]);
  e.licence = AsText(row[5]);
  e.created_utime = AsInt(row[6]);
  e.modified_utime = AsInt(row[7]);
  e.latest_version = static_cast<int>(AsInt(row[8]));
  if (!std::holds_alternative<std::monostate>(row[9])) {
    e.fabric = FabricParameters{AsDouble(row[9]),  AsDouble(row[10]), AsDouble(row[11]),
                                AsDouble(row[12]), AsDouble(row[13]), AsDouble(row[14])};
  }
  return e;
}

std::vector<SqlValue> FabricValues(std::int64_t id, const FabricParameters& f) {
  return {id,        f.mass_per_area, f.stretch_stiffness, f.shear_stiffness, f.bend_stiffness,
          f.damping, f.friction};
}

/// "sqlite:<path>" or "sqlite://<path>" → path; a bare path is itself.
std::string SqlitePath(const std::string& url) {
  if (url.rfind("sqlite:", 0) != 0) return url;
  std::string path = url.substr(7);
  if (path.rfind("//", 0) == 0) path = path.substr(2);
  return path;
}

}  // namespace

std::string RedactedUrl(const std::string& url) {
  const auto scheme = url.find("://");
  const auto at = url.rfind('@');
  if (scheme == std::string::npos || at == std::string::npos || at < scheme) return url;
  const auto colon = url.find(':', scheme + 3);
  if (colon == std::string::npos || colon > at) return url;
  return url.substr(0, colon + 1) + "***" + url.substr(at);
}

namespace {

bool IsPostgresUrl(const std::string& url) {
  return url.rfind("postgresql://", 0) == 0 || url.rfind("postgres://", 0) == 0;
}

/// Longest entry name or version label [bytes]: a name stands under a thumbnail and on one
/// line of `costume-catalog list`; 200 bytes is some 50–200 characters of UTF-8.
constexpr std::size_t kMaxNameBytes = 200;

/// Throws InputError unless `text` is at most kMaxNameBytes long, holds no control character
/// (a line break split `list`'s rows) and, when `required`, is not empty.
void RequireName(const std::string& where, const std::string& field, const std::string& text,
                 bool required) {
  const bool control = std::any_of(text.begin(), text.end(), [](char c) {
    const auto byte = static_cast<unsigned char>(c);
    return byte < 0x20 || byte == 0x7f;
  });
  if ((required && text.empty()) || text.size() > kMaxNameBytes || control) {
    throw sim::InputError(where + ": " + field + " '" + sim::QuoteForMessage(text) + "' (" +
                          std::to_string(text.size()) + " bytes) is not allowed: " +
                          (required ? "1" : "0") + " to " + std::to_string(kMaxNameBytes) +
                          " bytes without control characters such as line breaks");
  }
}

void CheckNewEntry(const NewEntry& entry, const std::string& url) {
  RequireName("catalog '" + url + "'", std::string(KindName(entry.kind)) + " name", entry.name,
              true);
  const std::string what = std::string(KindName(entry.kind)) + " '" + entry.name + "'";
  if (entry.kind == Kind::kGarment) {
    RequireName("catalog '" + url + "': " + what, "version label", entry.version_label, false);
  }
  if (entry.kind == Kind::kAnimation && entry.category != "basic" &&
      entry.category != "choreography") {
    throw sim::InputError("catalog '" + url + "': " + what + ": category = '" + entry.category +
                          "': allowed are basic, choreography");
  }
  if (entry.kind == Kind::kGarment && !entry.fabric) {
    throw sim::InputError("catalog '" + url + "': " + what + " needs fabric parameters");
  }
  if (entry.fabric) ValidateFabric(*entry.fabric, what);
  if (entry.data.format.empty() || entry.data.bytes.empty()) {
    throw sim::InputError("catalog '" + url + "': " + what + " has no data");
  }
}

/// Inserts a checked entry with its first version; the caller holds a write transaction.
std::int64_t InsertEntry(SqlConnection& db, const NewEntry& entry, const std::string& url) {
  const auto taken = db.Query("SELECT id FROM entries WHERE kind = $1 AND name = $2",
                              {std::string(KindName(entry.kind)), entry.name});
  if (!taken.empty()) {
    throw sim::InputError("catalog '" + url + "': there is already a " + KindName(entry.kind) +
                          " '" + entry.name + "' (id " + std::to_string(AsInt(taken[0][0])) +
                          "): choose another name");
  }
  const std::int64_t now = NowUtime();
  const std::int64_t id =
      AsInt(db.Query("INSERT INTO entries (kind, name, category, provenance, licence, "
                     "created_utime, modified_utime, latest_version) "
                     "VALUES ($1, $2, $3, $4, $5, $6, $6, 1) RETURNING id",
                     {std::string(KindName(entry.kind)), entry.name, entry.category,
                      entry.provenance, entry.licence, now})
                .at(0)
                .at(0));
  if (entry.fabric) {
    db.Execute("INSERT INTO fabrics VALUES ($1, $2, $3, $4, $5, $6, $7)",
               FabricValues(id, *entry.fabric));
  }
  db.Execute(
      "INSERT INTO versions (entry_id, version, label, created_utime, format, data, thumbnail) "
      "VALUES ($1, 1, $2, $3, $4, $5, $6)",
      {id, entry.kind == Kind::kGarment ? entry.version_label : std::string(), now,
       entry.data.format, entry.data.bytes,
       entry.thumbnail_png.empty() ? SqlValue{} : SqlValue{entry.thumbnail_png}});
  return id;
}

/// The built-in entries, with thumbnails when `options` has a maker.
std::vector<NewEntry> BuiltInEntries(const OpenOptions& options) {
  std::vector<NewEntry> entries;
  auto add = [&](Kind kind, const std::string& name, const std::string& category,
                 std::optional<FabricParameters> fabric) {
    NewEntry e;
    e.kind = kind;
    e.name = name;
    e.category = category;
    e.provenance = kBuiltInProvenance;
    e.licence = kBuiltInLicence;
    e.fabric = fabric;
    e.data = {"builtin", std::vector<std::uint8_t>(name.begin(), name.end())};
    if (options.thumbnails) {
      try {
        ThumbnailRequest request =
            CheckAssetData(kind, name, e.data, fabric.value_or(FabricParameters{}), name);
        request.size = options.thumbnail_size;
        e.thumbnail_png = options.thumbnails(request);
      } catch (const sim::InputError& error) {
        std::cerr << "warning: no thumbnail for built-in " << KindName(kind) << " '" << name
                  << "': " << error.what() << "\n";
      }
    }
    entries.push_back(std::move(e));
  };
  add(Kind::kAvatar, "humanoid", "", std::nullopt);
  for (const std::string& clip : sim::BuiltInClipNames()) {
    add(Kind::kAnimation, clip, clip == "dance" ? "choreography" : "basic", std::nullopt);
  }
  for (const std::string& garment : sim::BuiltInGarmentNames()) {
    add(Kind::kGarment, garment, "pattern", BuiltInGarmentFabric());
  }
  return entries;
}

}  // namespace

const char* KindName(Kind kind) {
  switch (kind) {
    case Kind::kAvatar:
      return "avatar";
    case Kind::kGarment:
      return "garment";
    case Kind::kAnimation:
      return "animation";
  }
  return "unknown";
}

const std::vector<std::string>& AvatarFileFormats() {
  static const std::vector<std::string> formats{"glb", "gltf", "vrm", "fbx", "dae", "obj"};
  return formats;
}

const std::vector<std::string>& AnimationFileFormats() {
  static const std::vector<std::string> formats{"glb", "gltf", "fbx", "dae"};
  return formats;
}

bool HasFormat(const std::vector<std::string>& formats, const std::string& format) {
  return std::find(formats.begin(), formats.end(), format) != formats.end();
}

std::string ListFormats(const std::vector<std::string>& formats, const std::string& prefix) {
  std::string list;
  for (const std::string& format : formats) list += (list.empty() ? "" : ", ") + prefix + format;
  return list;
}

Kind ParseKind(const std::string& name) {
  for (Kind kind : {Kind::kAvatar, Kind::kGarment, Kind::kAnimation}) {
    if (name == KindName(kind)) return kind;
  }
  throw sim::InputError("kind = '" + name + "': allowed are avatar, garment, animation");
}

FabricParameters FabricFromMaterial(const sim::Material& m) {
  return {m.density,          m.stretch_stiffness, m.shear_stiffness,
          m.bending_rigidity, m.damping,           m.friction};
}

sim::Material MaterialFromFabric(const FabricParameters& f, const std::string& name) {
  sim::Material m;
  m.name = name;
  m.density = f.mass_per_area;
  m.stretch_stiffness = f.stretch_stiffness;
  m.shear_stiffness = f.shear_stiffness;
  m.bending_rigidity = f.bend_stiffness;
  m.damping = f.damping;
  m.friction = f.friction;
  return m;
}

void ValidateFabric(const FabricParameters& f, const std::string& context) {
  const std::string prefix = context + ": fabric.";
  sim::RequirePositiveAtMost(prefix + "mass_per_area", f.mass_per_area, sim::kMaxDensity,
                             "kg/m²");
  sim::RequirePositiveAtMost(prefix + "stretch_stiffness", f.stretch_stiffness,
                             sim::kMaxStiffness, "N/m");
  sim::RequirePositiveAtMost(prefix + "shear_stiffness", f.shear_stiffness, sim::kMaxStiffness,
                             "N/m");
  sim::RequireInRange(prefix + "bend_stiffness", f.bend_stiffness, 0.0, sim::kMaxBendingRigidity,
                      "N·m");
  sim::RequireInRange(prefix + "damping", f.damping, 0.0, sim::kMaxDamping, "s");
  sim::RequireInRange(prefix + "friction", f.friction, 0.0, sim::kMaxFriction, "");
}

std::string DefaultCatalogUrl() {
  if (const char* url = std::getenv("COSTUME_CATALOG"); url && *url) return url;
  std::string data_home;
  if (const char* xdg = std::getenv("XDG_DATA_HOME"); xdg && *xdg) {
    data_home = xdg;
  } else if (const char* home = std::getenv("HOME"); home && *home) {
    data_home = std::string(home) + "/.local/share";
  } else {
    data_home = ".";
  }
  return "sqlite:" + data_home + "/costume-designer/catalog.sqlite";
}

// ---- Catalog -------------------------------------------------------------------------------

std::unique_ptr<Catalog> Catalog::Open(const std::string& url, const OpenOptions& options) {
  if (url.empty()) {
    throw sim::InputError("catalog URL is empty: give sqlite:<path>, a path or postgresql://...");
  }
  std::unique_ptr<SqlConnection> connection;
  if (IsPostgresUrl(url)) {
    connection = OpenPostgres(url);
  } else if (url.rfind("sqlite:", 0) != 0 && url.find("://") != std::string::npos) {
    throw sim::InputError("catalog '" + url + "': unknown scheme '" +
                          url.substr(0, url.find("://")) +
                          "': allowed are sqlite:<path>, a bare path, postgresql://, "
                          "postgres://");
  } else {
    connection = OpenSqlite(SqlitePath(url), url);
  }
  std::unique_ptr<Catalog> catalog(new Catalog(RedactedUrl(url), std::move(connection)));
  catalog->Migrate();
  if (options.seed) catalog->Seed(options);
  return catalog;
}

Catalog::Catalog(std::string url, std::unique_ptr<SqlConnection> connection)
    : url_(std::move(url)), db_(std::move(connection)) {}

Catalog::~Catalog() = default;

void Catalog::Migrate() {
  InTransaction(*db_, true, [&] {
    db_->Execute(
        "CREATE TABLE IF NOT EXISTS schema_migrations (version INTEGER PRIMARY KEY, "
        "description TEXT NOT NULL, applied_utime BIGINT NOT NULL)");
    const auto rows = db_->Query("SELECT MAX(version) FROM schema_migrations");
    const int current = static_cast<int>(AsInt(rows.at(0).at(0)));
    const int newest = std::size(kMigrations);
    if (current > newest) {
      throw sim::InputError("catalog '" + url_ + "': schema version " + std::to_string(current) +
                            " is newer than this program knows (" + std::to_string(newest) +
                            "): update the program");
    }
    for (const Migration& m : kMigrations) {
      if (m.version <= current) continue;
      db_->Execute(ForDialect(m.sql, db_->dialect()));
      db_->Execute(
          "INSERT INTO schema_migrations (version, description, applied_utime) "
          "VALUES ($1, $2, $3)",
          {std::int64_t{m.version}, std::string(m.description), NowUtime()});
    }
  });
}

int Catalog::schema_version() {
  return static_cast<int>(
      AsInt(db_->Query("SELECT MAX(version) FROM schema_migrations").at(0).at(0)));
}

void Catalog::Seed(const OpenOptions& options) {
  auto is_empty = [this] {
    return AsInt(db_->Query("SELECT COUNT(*) FROM entries").at(0).at(0)) == 0;
  };
  if (!is_empty()) return;
  // Thumbnails are rendered outside the lock; a second process seeding at the same time
  // finds the entries there once it holds the lock and adds nothing.
  const std::vector<NewEntry> entries = BuiltInEntries(options);
  InTransaction(*db_, true, [&] {
    if (!is_empty()) return;
    for (const NewEntry& e : entries) {
      CheckNewEntry(e, url_);
      InsertEntry(*db_, e, url_);
    }
  });
}

std::vector<EntryInfo> Catalog::List(Kind kind) {
  std::vector<EntryInfo> entries;
  for (const SqlRow& row :
       db_->Query(std::string(kEntryColumns) + "WHERE e.kind = $1 ORDER BY e.name",
                  {std::string(KindName(kind))})) {
    entries.push_back(ToEntry(row));
  }
  return entries;
}

std::optional<EntryInfo> Catalog::Find(Kind kind, const std::string& name) {
  const auto rows = db_->Query(std::string(kEntryColumns) + "WHERE e.kind = $1 AND e.name = $2",
                               {std::string(KindName(kind)), name});
  if (rows.empty()) return std::nullopt;
  return ToEntry(rows[0]);
}

EntryInfo Catalog::Get(std::int64_t id) {
  const auto rows = db_->Query(std::string(kEntryColumns) + "WHERE e.id = $1", {id});
  if (rows.empty()) {
    throw sim::InputError("catalog '" + url_ + "': no entry with id " + std::to_string(id));
  }
  return ToEntry(rows[0]);
}

std::vector<std::uint8_t> Catalog::Thumbnail(std::int64_t id) {
  const auto rows = db_->Query(
      "SELECT v.thumbnail FROM versions v JOIN entries e ON e.id = v.entry_id "
      "WHERE e.id = $1 AND v.version = e.latest_version",
      {id});
  if (rows.empty()) {
    throw sim::InputError("catalog '" + url_ + "': no entry with id " + std::to_string(id));
  }
  return AsBlob(rows[0][0]);
}

AssetData Catalog::Data(std::int64_t id, int version) {
  // One statement: it reads the latest version number and that version's bytes from the
  // same snapshot, so a save committing meanwhile is seen whole or not at all.
  const auto rows =
      version == 0
          ? db_->Query(
                "SELECT v.format, v.data FROM versions v JOIN entries e ON "
                "e.id = v.entry_id WHERE e.id = $1 AND v.version = e.latest_version",
                {id})
          : db_->Query("SELECT format, data FROM versions WHERE entry_id = $1 AND version = $2",
                       {id, std::int64_t{version}});
  if (rows.empty()) {
    const EntryInfo entry = Get(id);  // throws for an unknown id
    throw sim::InputError("catalog '" + url_ + "': " + KindName(entry.kind) + " '" + entry.name +
                          "' has no version " + std::to_string(version) + ": versions are 1 to " +
                          std::to_string(entry.latest_version));
  }
  return {AsText(rows[0][0]), AsBlob(rows[0][1])};
}

std::vector<VersionInfo> Catalog::Versions(std::int64_t garment_id) {
  return InTransaction(*db_, false, [&] {
    const EntryInfo entry = Get(garment_id);
    if (entry.kind != Kind::kGarment) {
      throw sim::InputError("catalog '" + url_ + "': entry " + std::to_string(garment_id) + " ('" +
                            entry.name + "') is " + Article(entry.kind) + KindName(entry.kind) +
                            ", not a garment: only garments have versions");
    }
    std::vector<VersionInfo> versions;
    for (const SqlRow& row :
         db_->Query("SELECT version, label, created_utime FROM versions WHERE entry_id = $1 "
                    "ORDER BY version",
                    {garment_id})) {
      versions.push_back({static_cast<int>(AsInt(row[0])), AsText(row[1]), AsInt(row[2])});
    }
    return versions;
  });
}

int Catalog::SaveGarmentVersion(std::int64_t garment_id, const AssetData& data,
                                const std::string& label,
                                const std::vector<std::uint8_t>& thumbnail_png) {
  if (data.format.empty() || data.bytes.empty()) {
    throw sim::InputError("catalog '" + url_ + "': garment " + std::to_string(garment_id) +
                          ": a version needs a format and data (got format '" + data.format +
                          "', " + std::to_string(data.bytes.size()) + " bytes)");
  }
  RequireName("catalog '" + url_ + "': garment " + std::to_string(garment_id), "version label",
              label, false);
  return InTransaction(*db_, true, [&] {
    const std::int64_t now = NowUtime();
    // Taking the next number and inserting it happen in one transaction under the write
    // lock; the (entry_id, version) key refuses any second row of the same number.
    const auto rows = db_->Query(
        "UPDATE entries SET latest_version = latest_version + 1, modified_utime = $2 "
        "WHERE id = $1 AND kind = 'garment' RETURNING latest_version",
        {garment_id, now});
    if (rows.empty()) {
      const EntryInfo entry = Get(garment_id);  // throws for an unknown id
      throw sim::InputError("catalog '" + url_ + "': entry " + std::to_string(garment_id) + " ('" +
                            entry.name + "') is " + Article(entry.kind) + KindName(entry.kind) +
                            ", not a garment: only garments take new versions");
    }
    const std::int64_t version = AsInt(rows[0][0]);
    db_->Execute(
        "INSERT INTO versions (entry_id, version, label, created_utime, format, data, thumbnail) "
        "VALUES ($1, $2, $3, $4, $5, $6, $7)",
        {garment_id, version, label, now, data.format, data.bytes,
         thumbnail_png.empty() ? SqlValue{} : SqlValue{thumbnail_png}});
    return static_cast<int>(version);
  });
}

std::int64_t Catalog::Add(const NewEntry& entry) {
  CheckNewEntry(entry, url_);
  return InTransaction(*db_, true, [&] { return InsertEntry(*db_, entry, url_); });
}

std::vector<std::int64_t> Catalog::AddAll(const std::vector<NewEntry>& entries) {
  for (const NewEntry& entry : entries) CheckNewEntry(entry, url_);
  return InTransaction(*db_, true, [&] {
    std::vector<std::int64_t> ids;
    for (const NewEntry& entry : entries) ids.push_back(InsertEntry(*db_, entry, url_));
    return ids;
  });
}

void Catalog::SetFabric(std::int64_t garment_id, const FabricParameters& fabric) {
  InTransaction(*db_, true, [&] {
    const EntryInfo entry = Get(garment_id);
    if (entry.kind != Kind::kGarment) {
      throw sim::InputError("catalog '" + url_ + "': entry " + std::to_string(garment_id) + " ('" +
                            entry.name + "') is " + Article(entry.kind) + KindName(entry.kind) +
                            ", not a garment: only garments have a fabric");
    }
    ValidateFabric(fabric, "garment '" + entry.name + "'");
    db_->Execute("DELETE FROM fabrics WHERE entry_id = $1", {garment_id});
    db_->Execute("INSERT INTO fabrics VALUES ($1, $2, $3, $4, $5, $6, $7)",
                 FabricValues(garment_id, fabric));
    db_->Execute("UPDATE entries SET modified_utime = $2 WHERE id = $1", {garment_id, NowUtime()});
  });
}

EntryInfo Catalog::Remove(std::int64_t id) {
  return InTransaction(*db_, true, [&] {
    const EntryInfo entry = Get(id);
    if (entry.provenance == kBuiltInProvenance) {
      throw sim::InputError("catalog '" + url_ + "': " + KindName(entry.kind) + " '" + entry.name +
                            "' (id " + std::to_string(id) +
                            ") is built in: scenes and the other entries may name it, so it stays");
    }
    // Children first: SQLite applies ON DELETE CASCADE only with its foreign keys on.
    db_->Execute("DELETE FROM fabrics WHERE entry_id = $1", {id});
    db_->Execute("DELETE FROM versions WHERE entry_id = $1", {id});
    db_->Execute("DELETE FROM entries WHERE id = $1", {id});
    return entry;
  });
}

void Catalog::SetThumbnail(std::int64_t id, const std::vector<std::uint8_t>& png) {
  InTransaction(*db_, true, [&] {
    const EntryInfo entry = Get(id);
    db_->Execute(
        "UPDATE versions SET thumbnail = $3 WHERE entry_id = $1 AND version = $2",
        {id, std::int64_t{entry.latest_version}, png.empty() ? SqlValue{} : SqlValue{png}});
  });
}

int Catalog::FillMissingThumbnails(const ThumbnailMaker& maker, int size, std::ostream& log) {
  int made = 0;
  for (Kind kind : {Kind::kAvatar, Kind::kAnimation, Kind::kGarment}) {
    for (const EntryInfo& entry : List(kind)) {
      if (!Thumbnail(entry.id).empty()) continue;
      log << KindName(kind) << " '" << entry.name << "' (id " << entry.id << "): thumbnail... "
          << std::flush;  // draping a garment takes seconds: say what is being made
      try {
        ThumbnailRequest request = CheckStoredVersion(*this, entry, 0, entry.name);
        request.size = size;
        const std::vector<std::uint8_t> png = maker(request);
        if (png.empty()) {
          log << "none made\n";
          continue;
        }
        SetThumbnail(entry.id, png);
        ++made;
        log << "ok\n";
      } catch (const sim::InputError& error) {
        log << "not made: " << error.what() << "\n";
      }
    }
  }
  return made;
}

}  // namespace costume::catalog

namespace costume::catalog {

std::vector<std::string> Catalog::CheckIntegrity() {
  return InTransaction(*db_, false, [&] {
    std::vector<std::string> problems;
    if (db_->dialect() == Dialect::kSqlite) {
      for (const SqlRow& row : db_->Query("PRAGMA integrity_check")) {
        if (AsText(row.at(0)) != "ok") problems.push_back("integrity_check: " + AsText(row[0]));
      }
      for (const SqlRow& row : db_->Query("PRAGMA foreign_key_check")) {
        problems.push_back("foreign_key_check: table " + AsText(row.at(0)) + " row " +
                           std::to_string(AsInt(row.at(1))));
      }
    }
    for (const SqlRow& row :
         db_->Query("SELECT e.id, e.name, e.latest_version, COUNT(v.version), MIN(v.version), "
                    "MAX(v.version) FROM entries e LEFT JOIN versions v ON v.entry_id = e.id "
                    "GROUP BY e.id, e.name, e.latest_version "
                    "HAVING COUNT(v.version) <> e.latest_version OR MIN(v.version) <> 1 OR "
                    "MAX(v.version) <> e.latest_version OR COUNT(v.version) = 0")) {
      problems.push_back("entry " + std::to_string(AsInt(row[0])) + " ('" + AsText(row[1]) +
                         "'): latest_version " + std::to_string(AsInt(row[2])) + " but " +
                         std::to_string(AsInt(row[3])) + " version(s) stored");
    }
    for (const SqlRow& row :
         db_->Query("SELECT e.id, e.name FROM entries e WHERE (e.kind <> 'garment' AND "
                    "e.latest_version <> 1) OR (e.kind = 'garment' AND NOT EXISTS "
                    "(SELECT 1 FROM fabrics f WHERE f.entry_id = e.id))")) {
      problems.push_back("entry " + std::to_string(AsInt(row[0])) + " ('" + AsText(row[1]) +
                         "'): a garment without fabric or another kind with several versions");
    }
    // Names stored before they were checked (a line break in one split `list`'s rows).
    for (Kind kind : {Kind::kAvatar, Kind::kAnimation, Kind::kGarment}) {
      for (const EntryInfo& entry : List(kind)) {
        try {
          RequireName("entry " + std::to_string(entry.id), "name", entry.name, true);
        } catch (const sim::InputError& error) {
          problems.push_back(error.what());
        }
      }
    }
    return problems;
  });
}

}  // namespace costume::catalog
