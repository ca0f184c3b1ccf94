#pragma once
// A real PostgreSQL server for a test: a new cluster (initdb) in a temporary folder, serving on
// a Unix socket in that folder only (no TCP listener), on a port nobody else holds, stopped and
// removed when the test ends. As root the server runs as the `postgres` user (runuser), which
// owns the folder. Tests skip with the reason available() gives when PostgreSQL 15 is absent.
//
// Every wait is pg_ctl's own readiness wait (-w) with a generous bound: a loaded two-core box
// with a sanitizer build is slow, and a bound that is reached fails the test with the server's
// log in the message.
#include <fcntl.h>
#include <netinet/in.h>
#include <pwd.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace loopwire::test {

class PostgresServer {
public:
    // PostgreSQL 15's binaries (LOOPWIRE_PG_BIN overrides the folder); empty when usable.
    static std::filesystem::path bin() {
        const char* override = std::getenv("LOOPWIRE_PG_BIN");
        return override ? override : "/usr/lib/postgresql/15/bin";
    }
    static std::optional<std::string> unavailable() {
        if (!std::filesystem::exists(bin() / "initdb") || !std::filesystem::exists(bin() / "pg_ctl")) {
            return "PostgreSQL 15 is not installed (" + (bin() / "initdb").string() +
                   " missing): apt-get install postgresql-15, or run scripts/setup";
        }
        if (::geteuid() == 0 && !::getpwnam("postgres")) return "running as root without a `postgres` user to run the server";
        return std::nullopt;
    }

    // `hba`: the pg_hba.conf lines (local connections); trust for everyone unless told.
    explicit PostgresServer(const std::string& hba = "local all all trust\n") {
        std::string pattern = (std::filesystem::temp_directory_path() / "loopwire-pg-XXXXXX").string();
        if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
        folder_ = pattern;
        port_ = socket_number();
        if (::geteuid() == 0) {
            const passwd* user = ::getpwnam("postgres");
            if (::chown(folder_.c_str(), user->pw_uid, user->pw_gid) != 0) throw std::runtime_error("chown failed");
        }
        must(run({(bin() / "initdb").string(), "-D", data(), "-U", "postgres", "-A", "trust", "--no-sync", "-E", "UTF8"}),
             "initdb");
        std::ofstream(data() + "/pg_hba.conf") << hba;
        start();
    }
    ~PostgresServer() {
        if (running_) (void)run({(bin() / "pg_ctl").string(), "-D", data(), "-m", "immediate", "-w", "stop"});
        std::error_code ignored;
        std::filesystem::remove_all(folder_, ignored);
    }
    PostgresServer(const PostgresServer&) = delete;
    PostgresServer& operator=(const PostgresServer&) = delete;

    void start() {
        // fsync off: the tests crash the gateway, not the server; durability of the server's
        // own files is not what they check, and the disk is shared.
        const std::string settings = "-k " + folder_.string() + " -p " + std::to_string(port_) +
                                     " -c listen_addresses= -c fsync=off -c max_connections=40";
        must(run({(bin() / "pg_ctl").string(), "-D", data(), "-l", log_file(), "-w", "-t", "180", "-o", settings, "start"}),
             "pg_ctl start");
        running_ = true;
    }
    void stop() {
        must(run({(bin() / "pg_ctl").string(), "-D", data(), "-m", "fast", "-w", "-t", "180", "stop"}), "pg_ctl stop");
        running_ = false;
    }

    // key=value connection strings for a database and user on this server.
    std::string conninfo(const std::string& database = "postgres", const std::string& user = "postgres") const {
        return "host=" + folder_.string() + " port=" + std::to_string(port_) + " dbname=" + database + " user=" + user;
    }
    std::string url(const std::string& database = "postgres", const std::string& user = "postgres") const {
        return "postgresql://" + user + "@/" + database + "?host=" + folder_.string() + "&port=" + std::to_string(port_);
    }
    const std::filesystem::path& folder() const { return folder_; }
    int port() const { return port_; }

private:
    std::string data() const { return (folder_ / "data").string(); }
    std::string log_file() const { return (folder_ / "server.log").string(); }

    // The number in the name of the server's Unix socket: the server listens on no TCP port
    // (listen_addresses is empty) and its socket lies in its own folder, so nothing can race
    // for the number. One the kernel had free, as a fixed number would read as if it mattered.
    static int socket_number() {
        const int s = ::socket(AF_INET, SOCK_STREAM, 0);
        sockaddr_in address{};
        address.sin_family = AF_INET;
        address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        socklen_t size = sizeof address;
        int port = 54329;
        if (s >= 0 && ::bind(s, reinterpret_cast<sockaddr*>(&address), size) == 0 &&
            ::getsockname(s, reinterpret_cast<sockaddr*>(&address), &size) == 0) {
            port = ntohs(address.sin_port);
        }
        if (s >= 0) ::close(s);
        return port;
    }

    void must(int status, const std::string& what) const {
        if (status == 0) return;
        std::ifstream log(log_file());
        std::stringstream text;
        text << log.rdbuf();
        std::ifstream output(folder_ / "command.log");
        text << output.rdbuf();
        throw std::runtime_error(what + " failed (status " + std::to_string(status) + "):\n" + text.str());
    }

    // Runs a PostgreSQL program, as `postgres` when root (the server refuses to run as root),
    // its output into command.log; the exit status.
    int run(std::vector<std::string> argv) const {
        if (::geteuid() == 0) argv.insert(argv.begin(), {"runuser", "-u", "postgres", "--"});
        // Everything the child needs is made before fork(): between fork and exec a child of a
        // threaded process may only make async-signal-safe calls.
        const std::string out = (folder_ / "command.log").string();
        std::vector<char*> args;
        for (auto& a : argv) args.push_back(a.data());
        args.push_back(nullptr);
        const pid_t child = ::fork();
        if (child == 0) {
            const int f = ::open(out.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
            if (f >= 0) {
                ::dup2(f, 1);
                ::dup2(f, 2);
            }
            ::execvp(args[0], args.data());
            ::_exit(127);
        }
        int status = 0;
        if (child < 0 || ::waitpid(child, &status, 0) != child) return -1;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    }

    std::filesystem::path folder_;
    int port_ = 0;
    bool running_ = false;
};

}  // namespace loopwire::test
