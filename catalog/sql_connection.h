#pragma once
/// @file
/// The small SQL interface the catalogue is written against, with one implementation per
/// database (SQLite's and libpq's C APIs). Statements use PostgreSQL's numbered parameters
/// ($1, $2, ...), which the SQLite side rewrites to ?1, ?2, ...; everything else is the SQL
/// both databases accept (the schema's few differences are asked of the Dialect).
/// Internal to the catalog library.

#include <cstdint>
#include <memory>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

namespace costume::catalog {

/// Bytes stored as a BLOB (SQLite) or BYTEA (PostgreSQL).
using Blob = std::vector<std::uint8_t>;

/// One parameter or result value: NULL, integer, real, text or bytes.
using SqlValue = std::variant<std::monostate, std::int64_t, double, std::string, Blob>;

/// One result row, columns in SELECT order.
using SqlRow = std::vector<SqlValue>;

/// Where the two databases' SQL differs.
enum class Dialect { kSqlite, kPostgres };

/// A connection to one database. Methods throw sim::InputError naming the URL and quoting
/// the database's message.
class SqlConnection {
 public:
  virtual ~SqlConnection() = default;
  virtual Dialect dialect() const = 0;
  /// Runs one statement (or, without parameters, several separated by ';').
  virtual void Execute(const std::string& sql, const std::vector<SqlValue>& params = {}) = 0;
  /// Runs one statement and returns its rows.
  virtual std::vector<SqlRow> Query(const std::string& sql,
                                    const std::vector<SqlValue>& params = {}) = 0;
  /// Starts a transaction that will write: SQLite takes the write lock at once (BEGIN
  /// IMMEDIATE, waiting up to the busy timeout); PostgreSQL also takes the catalogue's
  /// advisory lock, so that writers (and first-run seeding) queue instead of conflicting.
  virtual void BeginWrite() = 0;
  /// Starts a read transaction: every query until Commit sees one snapshot.
  virtual void BeginRead() = 0;
  virtual void Commit() = 0;
  /// Never throws (used while unwinding).
  virtual void Rollback() noexcept = 0;
};

/// A SQLite database file at `path` (created when missing, with its directory), in WAL mode
/// with a busy timeout; `url` is quoted in messages.
std::unique_ptr<SqlConnection> OpenSqlite(const std::string& path, const std::string& url);

/// A PostgreSQL connection (libpq connection string or URI `url`).
std::unique_ptr<SqlConnection> OpenPostgres(const std::string& url);

/// Runs `body` inside a transaction begun by `begin` (BeginWrite or BeginRead), committing
/// when it returns and rolling back when it throws.
template <typename Body>
auto InTransaction(SqlConnection& db, bool write, Body&& body) {
  if (write) {
    db.BeginWrite();
  } else {
    db.BeginRead();
  }
  try {
    if constexpr (std::is_void_v<decltype(body())>) {
      body();
      db.Commit();
    } else {
      auto result = body();
      db.Commit();
      return result;
    }
  } catch (...) {
    db.Rollback();
    throw;
  }
}

}  // namespace costume::catalog
