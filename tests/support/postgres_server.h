#pragma once
/// @file
/// A throwaway PostgreSQL server for tests: initdb into a fresh temporary folder, pg_ctl start
/// on 127.0.0.1 at a free port with its unix socket in that folder, stopped and removed at
/// destruction. Run as the `postgres` user when the tests run as root (PostgreSQL refuses to
/// run as root). When no PostgreSQL binaries are found, scripts/install_deps.sh is run once
/// (root only); if they are still missing, `skip_reason()` says why and tests GTEST_SKIP.

#include <sys/socket.h>
#include <sys/stat.h>
#include <netinet/in.h>
#include <pwd.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

namespace costume::test {

class PostgresServer {
 public:
  /// The server shared by the tests of this process (started on first use).
  static PostgresServer& Shared() {
    static PostgresServer server;
    return server;
  }

  /// Empty when the server runs; else why not (for GTEST_SKIP or a failure message).
  const std::string& skip_reason() const { return skip_reason_; }
  /// True when binaries were found but the server did not start (a real failure).
  bool failed() const { return failed_; }

  /// A URL for a new, empty database of this server.
  std::string NewDatabaseUrl() {
    const std::string name = "catalog_test_" + std::to_string(++databases_);
    Run(Psql("CREATE DATABASE " + name));
    return "postgresql://postgres@127.0.0.1:" + std::to_string(port_) + "/" + name;
  }

  int port() const { return port_; }

  ~PostgresServer() {
    if (started_)
      Run(AsOwner(bin_ + "/pg_ctl -D " + dir_ + "/data -m immediate -w stop") + " >/dev/null 2>&1");
    if (!dir_.empty()) {
      std::error_code error;
      std::filesystem::remove_all(dir_, error);
    }
  }

 private:
  PostgresServer() { Start(); }

  void Start() {
    bin_ = FindBinaries();
    if (bin_.empty() && geteuid() == 0 && std::filesystem::exists("scripts/install_deps.sh")) {
      Run("bash scripts/install_deps.sh >/dev/null 2>&1");
      bin_ = FindBinaries();
    }
    if (bin_.empty()) {
      skip_reason_ =
          "no PostgreSQL server binaries (initdb, pg_ctl) under /usr/lib/postgresql "
          "even after scripts/install_deps.sh: install the package 'postgresql'";
      return;
    }
    char pattern[] = "/tmp/costume-pg-XXXXXX";
    if (!mkdtemp(pattern)) return Fail("mkdtemp failed");
    dir_ = pattern;
    if (geteuid() == 0) {
      const passwd* user = getpwnam("postgres");
      if (!user) return Fail("running as root and there is no 'postgres' user to run the server");
      if (chown(dir_.c_str(), user->pw_uid, user->pw_gid) != 0) return Fail("chown failed");
      run_as_ = "runuser -u postgres -- ";
    }
    port_ = FreePort();
    if (Run(AsOwner(bin_ + "/initdb -D " + dir_ +
                    "/data -U postgres --auth=trust -E UTF8 "
                    "--no-sync") +
            " >" + dir_ + "/initdb.log 2>&1") != 0) {
      return Fail("initdb failed: " + ReadFile(dir_ + "/initdb.log"));
    }
    // Loopback only, socket in our folder; fsync off: the tests kill client processes, not
    // the machine, so durability across power loss is not what they check.
    const std::string options = "-c listen_addresses=127.0.0.1 -p " + std::to_string(port_) +
                                " -k " + dir_ + " -c fsync=off -c max_connections=40";
    if (Run(AsOwner(bin_ + "/pg_ctl -D " + dir_ + "/data -o '" + options + "' -l " + dir_ +
                    "/server.log -w -t 60 start") +
            " >/dev/null 2>&1") != 0) {
      return Fail("pg_ctl start failed: " + ReadFile(dir_ + "/server.log"));
    }
    started_ = true;
  }

  void Fail(const std::string& why) {
    failed_ = true;
    skip_reason_ = "PostgreSQL test server: " + why;
  }

  static std::string FindBinaries() {
    namespace fs = std::filesystem;
    std::error_code error;
    std::string best;
    for (const auto& version : fs::directory_iterator("/usr/lib/postgresql", error)) {
      const std::string bin = version.path().string() + "/bin";
      if (fs::exists(bin + "/initdb") && fs::exists(bin + "/pg_ctl") && bin > best) best = bin;
    }
    return best;
  }

  static int FreePort() {
    const int s = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = 0;
    socklen_t length = sizeof address;
    bind(s, reinterpret_cast<sockaddr*>(&address), sizeof address);
    getsockname(s, reinterpret_cast<sockaddr*>(&address), &length);
    const int port = ntohs(address.sin_port);
    close(s);
    return port;
  }

  std::string AsOwner(const std::string& command) const { return run_as_ + command; }

  std::string Psql(const std::string& sql) const {
    return AsOwner(bin_ + "/psql -q -h " + dir_ + " -p " + std::to_string(port_) +
                   " -U postgres -d postgres -c \"" + sql + "\"") +
           " >/dev/null";
  }

  static int Run(const std::string& command) { return std::system(command.c_str()); }

  static std::string ReadFile(const std::string& path) {
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    return text.str().substr(0, 2000);
  }

  std::string bin_, dir_, run_as_, skip_reason_;
  int port_ = 0;
  int databases_ = 0;
  bool started_ = false;
  bool failed_ = false;
};

}  // namespace costume::test
