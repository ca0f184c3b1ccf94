#pragma once
// Logins on the HTTP API: the sessions a login opens (a cookie names one), the limit on failed
// logins from one address, and the parsers of what a browser sends (the login body, the Cookie
// header). Time is injected, so that expiry and the limiter's delays are tested in virtual time.
//
// Threads: SessionStore and LoginLimiter lock inside; any thread may call them (logins are
// checked off the network thread, Argon2id being slow on purpose).
#include <chrono>
#include <cstddef>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <condition_variable>
#include <deque>

#include "gateway/http_users.hpp"

namespace loopwire::gateway {

using SteadyClock = std::function<std::chrono::steady_clock::time_point()>;

struct Session {
    std::string id;    // 32 random bytes, base64url: the cookie's value
    std::string csrf;  // 32 random bytes, base64url: what X-CSRF-Token must say on a write
    std::string user;
    Role role = Role::viewer;
    std::chrono::steady_clock::time_point last_used;
};

inline constexpr std::string_view session_cookie = "loopwire_session";

class SessionStore {
public:
    // A session not used for `idle_timeout` ends; at most `max_sessions` at once (the oldest
    // unused goes first), so logins cannot grow the gateway without end.
    SessionStore(std::chrono::milliseconds idle_timeout, SteadyClock clock = {}, std::size_t max_sessions = 10000);

    // A reload's [http] session_timeout, for the sessions open and those to come.
    void set_idle_timeout(std::chrono::milliseconds idle_timeout);

    Session open(const std::string& user, Role role);
    // The session `id` names, marked used now; none when unknown or expired (then removed).
    std::optional<Session> find(std::string_view id);
    void close(std::string_view id);
    // Ends every session of users no longer in `users`, or whose role changed (a reload).
    void keep_only(const std::vector<HttpUser>& users);
    std::size_t size() const;

private:
    std::chrono::steady_clock::time_point now() const;
    std::chrono::milliseconds idle_timeout_;
    SteadyClock clock_;
    std::size_t max_sessions_;
    mutable std::mutex mutex_;
    std::map<std::string, Session, std::less<>> sessions_;
};

// Failed logins by client address: the first `free_failures` cost nothing; each further one
// makes the address wait before it may try again, doubling from `first_delay` up to
// `longest_delay`. A success clears the address. An address quiet for a day is forgotten, and
// at most `max_addresses` are kept (the quietest go), so a scan of addresses cannot grow it.
class LoginLimiter {
public:
    struct Settings {
        unsigned free_failures = 5;
        std::chrono::seconds first_delay{1};
        std::chrono::seconds longest_delay{300};
        std::size_t max_addresses = 10000;
    };
    explicit LoginLimiter(Settings settings, SteadyClock clock = {});

    // How long `address` must still wait before a login is tried; none: it may try now.
    std::optional<std::chrono::seconds> wait_for(const std::string& address) const;
    // Counts a failure; returns the wait it now has (none while still within the free ones).
    std::optional<std::chrono::seconds> failed(const std::string& address);
    void succeeded(const std::string& address);

private:
    struct Record {
        unsigned failures = 0;
        std::chrono::steady_clock::time_point last;
        std::chrono::steady_clock::time_point blocked_until;
    };
    std::chrono::steady_clock::time_point now() const;
    Settings settings_;
    SteadyClock clock_;
    mutable std::mutex mutex_;
    std::map<std::string, Record> records_;
};

// Where logins' Argon2id checks run: one thread of its own, so that a login (about 0.1 s of CPU
// and 64 MiB) holds up neither the network thread nor, at once, more than one check's memory.
// At most `max_waiting` wait; post() refuses more. The destructor runs what still waits, then
// joins: each job answers its request exactly once.
class PasswordChecks {
public:
    explicit PasswordChecks(std::size_t max_waiting = 16);
    ~PasswordChecks();
    PasswordChecks(const PasswordChecks&) = delete;
    PasswordChecks& operator=(const PasswordChecks&) = delete;
    bool post(std::function<void()> job);

private:
    void run();
    std::size_t max_waiting_;
    std::mutex mutex_;
    std::condition_variable changed_;
    std::deque<std::function<void()>> jobs_;
    bool stopping_ = false;
    std::thread thread_;
};

// The logins a gateway keeps across reloads (GatewayOptions::http_logins): a SIGHUP that renews a
// certificate or adds a user logs nobody out; the sessions of users removed or given another
// role end (SessionStore::keep_only), and an address's failed logins still count.
struct HttpLogins {
    SessionStore sessions{std::chrono::hours(8)};
    LoginLimiter limiter{LoginLimiter::Settings{}};
};

// Compares in time independent of where they differ (tokens, CSRF tokens).
bool same_secret(std::string_view given, std::string_view expected);

struct LoginForm {
    std::string user;
    std::string password;
};
// POST /api/login's body: JSON {"user": ..., "password": ...}, or a form
// (application/x-www-form-urlencoded, user=...&password=...), by its Content-Type (JSON when
// it starts with '{' and none is given). None when it is neither or a field is missing.
std::optional<LoginForm> parse_login_body(std::string_view body, std::string_view content_type);

// The value of cookie `name` in a Cookie header ("a=1; loopwire_session=XYZ"); none when absent.
std::optional<std::string> cookie_value(std::string_view header, std::string_view name);

}  // namespace loopwire::gateway
