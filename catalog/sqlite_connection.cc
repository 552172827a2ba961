// SqlConnection over SQLite's C API: WAL mode so readers never block the writer and see the
// last committed state, a busy timeout so concurrent writers wait instead of failing.

#include <sqlite3.h>

#include <filesystem>
#include <memory>

#include "catalog/sql_connection.h"
#include "sim_core/common/input_error.h"

namespace costume::catalog {

namespace {

/// How long a statement waits for another process's lock before failing [ms].
constexpr int kBusyTimeoutMs = 30000;

/// Puts a new file into WAL mode, retrying while another process does the same. Switching
/// needs an exclusive lock, and when two connections race for it on a fresh file SQLite
/// answers SQLITE_BUSY at once, without calling the busy handler (its deadlock avoidance), so
/// the busy timeout alone does not cover two processes opening an empty catalogue together.
/// Any other outcome is left to the PRAGMA that follows, which reports it.
void SwitchToWal(sqlite3* db) {
  constexpr int kRetryMs = 5;
  for (int waited = 0; waited < kBusyTimeoutMs; waited += kRetryMs) {
    if (sqlite3_exec(db, "PRAGMA journal_mode = WAL;", nullptr, nullptr, nullptr) != SQLITE_BUSY) {
      return;
    }
    sqlite3_sleep(kRetryMs);
  }
}

/// $1, $2, ... → ?1, ?2, ... (the catalogue's SQL has no '$' elsewhere).
std::string ToSqliteParameters(std::string sql) {
  for (char& c : sql) {
    if (c == '$') c = '?';
  }
  return sql;
}

class SqliteConnection final : public SqlConnection {
 public:
  SqliteConnection(sqlite3* db, std::string url) : db_(db), url_(std::move(url)) {}
  ~SqliteConnection() override { sqlite3_close_v2(db_); }

  Dialect dialect() const override { return Dialect::kSqlite; }

  void Execute(const std::string& sql, const std::vector<SqlValue>& params) override {
    if (params.empty()) {
      char* message = nullptr;
      if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &message) != SQLITE_OK) {
        const std::string text = message ? message : sqlite3_errmsg(db_);
        sqlite3_free(message);
        Fail(text, sql);
      }
      return;
    }
    Query(sql, params);
  }

  std::vector<SqlRow> Query(const std::string& sql, const std::vector<SqlValue>& params) override {
    sqlite3_stmt* raw = nullptr;
    const std::string text = ToSqliteParameters(sql);
    if (sqlite3_prepare_v2(db_, text.c_str(), static_cast<int>(text.size()), &raw, nullptr) !=
        SQLITE_OK) {
      Fail(sqlite3_errmsg(db_), sql);
    }
    std::unique_ptr<sqlite3_stmt, int (*)(sqlite3_stmt*)> statement(raw, sqlite3_finalize);
    for (std::size_t i = 0; i < params.size(); ++i) Bind(raw, static_cast<int>(i + 1), params[i]);
    std::vector<SqlRow> rows;
    for (;;) {
      const int status = sqlite3_step(raw);
      if (status == SQLITE_DONE) break;
      if (status != SQLITE_ROW) Fail(sqlite3_errmsg(db_), sql);
      rows.push_back(ReadRow(raw));
    }
    return rows;
  }

  void BeginWrite() override { Execute("BEGIN IMMEDIATE", {}); }
  // DEFERRED: the snapshot is taken at the first read and kept until COMMIT (WAL mode).
  void BeginRead() override { Execute("BEGIN DEFERRED", {}); }
  void Commit() override { Execute("COMMIT", {}); }
  void Rollback() noexcept override {
    if (!sqlite3_get_autocommit(db_)) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }

 private:
  [[noreturn]] void Fail(const std::string& message, const std::string& sql) const {
    throw sim::InputError("catalog '" + url_ + "': SQLite: " + message +
                          " (in: " + sql.substr(0, 80) + ")");
  }

  void Bind(sqlite3_stmt* statement, int index, const SqlValue& value) {
    int status = SQLITE_OK;
    if (std::holds_alternative<std::monostate>(value)) {
      status = sqlite3_bind_null(statement, index);
    } else if (const auto* i = std::get_if<std::int64_t>(&value)) {
      status = sqlite3_bind_int64(statement, index, *i);
    } else if (const auto* d = std::get_if<double>(&value)) {
      status = sqlite3_bind_double(statement, index, *d);
    } else if (const auto* s = std::get_if<std::string>(&value)) {
      status = sqlite3_bind_text64(statement, index, s->data(), s->size(), SQLITE_TRANSIENT,
                                   SQLITE_UTF8);
    } else {
      const Blob& b = std::get<Blob>(value);
      // A zero-length blob must still be a blob, not NULL: bind a valid pointer.
      static const std::uint8_t kEmpty = 0;
      status = sqlite3_bind_blob64(statement, index, b.empty() ? &kEmpty : b.data(), b.size(),
                                   SQLITE_TRANSIENT);
    }
    if (status != SQLITE_OK) Fail(sqlite3_errmsg(db_), "bind");
  }

  static SqlRow ReadRow(sqlite3_stmt* statement) {
    SqlRow row;
    const int n = sqlite3_column_count(statement);
    for (int c = 0; c < n; ++c) {
      switch (sqlite3_column_type(statement, c)) {
        case SQLITE_INTEGER:
          row.emplace_back(static_cast<std::int64_t>(sqlite3_column_int64(statement, c)));
          break;
        case SQLITE_FLOAT:
          row.emplace_back(sqlite3_column_double(statement, c));
          break;
        case SQLITE_TEXT: {
          const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(statement, c));
          row.emplace_back(std::string(text, sqlite3_column_bytes(statement, c)));
          break;
        }
        case SQLITE_BLOB: {
          const auto* data = static_cast<const std::uint8_t*>(sqlite3_column_blob(statement, c));
          row.emplace_back(Blob(data, data + sqlite3_column_bytes(statement, c)));
          break;
        }
        default:
          row.emplace_back(std::monostate{});
      }
    }
    return row;
  }

  sqlite3* db_;
  std::string url_;
};

}  // namespace

std::unique_ptr<SqlConnection> OpenSqlite(const std::string& path, const std::string& url) {
  if (path.empty()) throw sim::InputError("catalog '" + url + "': no SQLite file path given");
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  std::error_code error;
  if (!parent.empty()) std::filesystem::create_directories(parent, error);
  if (error) {
    throw sim::InputError("catalog '" + url + "': cannot create the folder '" + parent.string() +
                          "': " + error.message());
  }
  sqlite3* db = nullptr;
  const int status = sqlite3_open_v2(
      path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
  if (status != SQLITE_OK) {
    const std::string message = db ? sqlite3_errmsg(db) : sqlite3_errstr(status);
    sqlite3_close_v2(db);
    throw sim::InputError("catalog '" + url + "': cannot open the SQLite file '" + path +
                          "': " + message);
  }
  auto connection = std::make_unique<SqliteConnection>(db, url);
  sqlite3_busy_timeout(db, kBusyTimeoutMs);
  SwitchToWal(db);
  // Reading the header here turns "not a database" into an error at open time.
  connection->Execute(
      "PRAGMA journal_mode = WAL; PRAGMA synchronous = FULL; "
      "PRAGMA foreign_keys = ON;",
      {});
  return connection;
}

}  // namespace costume::catalog
