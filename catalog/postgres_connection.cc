// SqlConnection over libpq: parameters sent as text (bytes as binary), results fetched in
// binary and decoded by column type. Writers serialise on one advisory lock.

#include <libpq-fe.h>

#include <bit>
#include <cstring>
#include <memory>

#include "catalog/catalog.h"
#include "catalog/sql_connection.h"
#include "sim_core/common/input_error.h"

namespace costume::catalog {

namespace {

// PostgreSQL type OIDs (server/catalog/pg_type_d.h, stable since 7.x).
constexpr Oid kBoolOid = 16;
constexpr Oid kByteaOid = 17;
constexpr Oid kInt8Oid = 20;
constexpr Oid kInt2Oid = 21;
constexpr Oid kInt4Oid = 23;
constexpr Oid kTextOid = 25;
constexpr Oid kFloat4Oid = 700;
constexpr Oid kFloat8Oid = 701;
constexpr Oid kVarcharOid = 1043;

/// The advisory lock every catalogue writer holds for its transaction ("CDCatalg").
constexpr long long kWriterLock = 0x434443617461'6c67LL;

/// A big-endian (network order) integer of `n` bytes.
std::uint64_t ReadBigEndian(const char* data, int n) {
  std::uint64_t value = 0;
  for (int i = 0; i < n; ++i) value = (value << 8) | static_cast<std::uint8_t>(data[i]);
  return value;
}

class PostgresConnection final : public SqlConnection {
 public:
  PostgresConnection(PGconn* connection, std::string url)
      : connection_(connection), url_(std::move(url)) {}
  ~PostgresConnection() override { PQfinish(connection_); }

  Dialect dialect() const override { return Dialect::kPostgres; }

  void Execute(const std::string& sql, const std::vector<SqlValue>& params) override {
    if (params.empty()) {
      Result result(PQexec(connection_, sql.c_str()));
      Check(result.get(), sql);
      return;
    }
    Query(sql, params);
  }

  std::vector<SqlRow> Query(const std::string& sql, const std::vector<SqlValue>& params) override {
    std::vector<std::string> texts(params.size());
    std::vector<const char*> values(params.size(), nullptr);
    std::vector<int> lengths(params.size(), 0);
    std::vector<int> formats(params.size(), 0);
    for (std::size_t i = 0; i < params.size(); ++i) {
      const SqlValue& p = params[i];
      if (const auto* v = std::get_if<std::int64_t>(&p)) {
        texts[i] = std::to_string(*v);
      } else if (const auto* d = std::get_if<double>(&p)) {
        char buffer[32];
        std::snprintf(buffer, sizeof buffer, "%.17g", *d);  // round-trips exactly
        texts[i] = buffer;
      } else if (const auto* s = std::get_if<std::string>(&p)) {
        texts[i] = *s;
      }
      if (const auto* b = std::get_if<Blob>(&p)) {
        static const char kEmpty = 0;
        values[i] = b->empty() ? &kEmpty : reinterpret_cast<const char*>(b->data());
        lengths[i] = static_cast<int>(b->size());
        formats[i] = 1;
      } else if (!std::holds_alternative<std::monostate>(p)) {
        values[i] = texts[i].c_str();
      }
    }
    Result result(PQexecParams(connection_, sql.c_str(), static_cast<int>(params.size()), nullptr,
                               values.data(), lengths.data(), formats.data(), /*binary=*/1));
    Check(result.get(), sql);
    std::vector<SqlRow> rows;
    const int num_rows = PQntuples(result.get());
    const int num_columns = PQnfields(result.get());
    rows.reserve(num_rows);
    for (int r = 0; r < num_rows; ++r) {
      SqlRow row;
      for (int c = 0; c < num_columns; ++c) row.push_back(Decode(result.get(), r, c, sql));
      rows.push_back(std::move(row));
    }
    return rows;
  }

  void BeginWrite() override {
    Execute("BEGIN ISOLATION LEVEL READ COMMITTED", {});
    Execute("SELECT pg_advisory_xact_lock(" + std::to_string(kWriterLock) + ")", {});
  }
  void BeginRead() override { Execute("BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY", {}); }
  void Commit() override { Execute("COMMIT", {}); }
  void Rollback() noexcept override {
    if (PQtransactionStatus(connection_) != PQTRANS_IDLE) PQclear(PQexec(connection_, "ROLLBACK"));
  }

 private:
  struct ResultDeleter {
    void operator()(PGresult* result) const { PQclear(result); }
  };
  using Result = std::unique_ptr<PGresult, ResultDeleter>;

  void Check(PGresult* result, const std::string& sql) const {
    const ExecStatusType status = PQresultStatus(result);
    if (status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK) return;
    std::string message = result ? PQresultErrorMessage(result) : PQerrorMessage(connection_);
    while (!message.empty() && message.back() == '\n') message.pop_back();
    throw sim::InputError("catalog '" + RedactedUrl(url_) + "': PostgreSQL: " + message +
                          " (in: " + sql.substr(0, 80) + ")");
  }

  SqlValue Decode(PGresult* result, int r, int c, const std::string& sql) const {
    if (PQgetisnull(result, r, c)) return std::monostate{};
    const char* data = PQgetvalue(result, r, c);
    const int length = PQgetlength(result, r, c);
    switch (PQftype(result, c)) {
      case kBoolOid:
        return static_cast<std::int64_t>(data[0] != 0);
      case kInt2Oid:
        return static_cast<std::int64_t>(static_cast<std::int16_t>(ReadBigEndian(data, 2)));
      case kInt4Oid:
        return static_cast<std::int64_t>(static_cast<std::int32_t>(ReadBigEndian(data, 4)));
      case kInt8Oid:
        return static_cast<std::int64_t>(ReadBigEndian(data, 8));
      case kFloat4Oid:
        return static_cast<double>(
            std::bit_cast<float>(static_cast<std::uint32_t>(ReadBigEndian(data, 4))));
      case kFloat8Oid:
        return std::bit_cast<double>(ReadBigEndian(data, 8));
      case kTextOid:
      case kVarcharOid:
        return std::string(data, length);
      case kByteaOid:
        return Blob(data, data + length);
      default:
        throw sim::InputError("catalog '" + RedactedUrl(url_) + "': PostgreSQL column " +
                              std::to_string(c) + " has an unexpected type (oid " +
                              std::to_string(PQftype(result, c)) + ") in: " + sql.substr(0, 80));
    }
  }

  PGconn* connection_;
  std::string url_;
};

}  // namespace

std::unique_ptr<SqlConnection> OpenPostgres(const std::string& url) {
  PGconn* connection = PQconnectdb(url.c_str());
  if (connection == nullptr || PQstatus(connection) != CONNECTION_OK) {
    std::string message = connection ? PQerrorMessage(connection) : "out of memory";
    PQfinish(connection);
    while (!message.empty() && message.back() == '\n') message.pop_back();
    throw sim::InputError("catalog '" + RedactedUrl(url) +
                          "': cannot connect to PostgreSQL: " + message);
  }
  auto result = std::make_unique<PostgresConnection>(connection, url);
  result->Execute("SET client_min_messages = warning", {});
  return result;
}

}  // namespace costume::catalog
