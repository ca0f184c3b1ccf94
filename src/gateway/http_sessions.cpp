#include "gateway/http_sessions.hpp"

#include <algorithm>
#include <cstdint>

#include <nlohmann/json.hpp>
#include <sodium.h>

#include "common/thread_name.hpp"
#include "gateway/http_text.hpp"

namespace loopwire::gateway {
namespace {

std::chrono::steady_clock::time_point now_from(const SteadyClock& clock) {
    return clock ? clock() : std::chrono::steady_clock::now();
}

std::string_view trimmed(std::string_view text) {
    while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
    while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
    return text;
}

}  // namespace

bool same_secret(std::string_view given, std::string_view expected) {
    if (given.size() != expected.size() || expected.empty()) return false;
    return ::sodium_memcmp(given.data(), expected.data(), expected.size()) == 0;
}

// ---------------------------------------------------------------------------------------------

SessionStore::SessionStore(std::chrono::milliseconds idle_timeout, SteadyClock clock, std::size_t max_sessions)
    : idle_timeout_(idle_timeout), clock_(std::move(clock)), max_sessions_(std::max<std::size_t>(max_sessions, 1)) {}

std::chrono::steady_clock::time_point SessionStore::now() const { return now_from(clock_); }

void SessionStore::set_idle_timeout(std::chrono::milliseconds idle_timeout) {
    std::lock_guard lock(mutex_);
    idle_timeout_ = idle_timeout;
}

Session SessionStore::open(const std::string& user, Role role) {
    Session session{random_secret(), random_secret(), user, role, now()};
    std::lock_guard lock(mutex_);
    std::erase_if(sessions_, [&](const auto& entry) { return session.last_used - entry.second.last_used >= idle_timeout_; });
    if (sessions_.size() >= max_sessions_) {
        auto oldest = std::min_element(sessions_.begin(), sessions_.end(), [](const auto& a, const auto& b) {
            return a.second.last_used < b.second.last_used;
        });
        sessions_.erase(oldest);
    }
    sessions_.emplace(session.id, session);
    return session;
}

std::optional<Session> SessionStore::find(std::string_view id) {
    const auto at = now();
    std::lock_guard lock(mutex_);
    auto it = sessions_.find(id);
    if (it == sessions_.end()) return std::nullopt;
    if (at - it->second.last_used >= idle_timeout_) {
        sessions_.erase(it);
        return std::nullopt;
    }
    it->second.last_used = at;
    return it->second;
}

void SessionStore::close(std::string_view id) {
    std::lock_guard lock(mutex_);
    if (auto it = sessions_.find(id); it != sessions_.end()) sessions_.erase(it);
}

void SessionStore::keep_only(const std::vector<HttpUser>& users) {
    std::lock_guard lock(mutex_);
    std::erase_if(sessions_, [&](const auto& entry) {
        return std::none_of(users.begin(), users.end(), [&](const HttpUser& user) {
            return user.name == entry.second.user && user.role == entry.second.role;
        });
    });
}

std::size_t SessionStore::size() const {
    std::lock_guard lock(mutex_);
    return sessions_.size();
}

// ---------------------------------------------------------------------------------------------

PasswordChecks::PasswordChecks(std::size_t max_waiting) : max_waiting_(max_waiting), thread_([this] { run(); }) {
    name_thread(thread_.native_handle(), "lw-login");
}

PasswordChecks::~PasswordChecks() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    changed_.notify_all();
    thread_.join();
}

bool PasswordChecks::post(std::function<void()> job) {
    {
        std::lock_guard lock(mutex_);
        if (stopping_ || jobs_.size() >= max_waiting_) return false;
        jobs_.push_back(std::move(job));
    }
    changed_.notify_all();
    return true;
}

void PasswordChecks::run() {
    std::unique_lock lock(mutex_);
    for (;;) {
        changed_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
        if (jobs_.empty()) return;  // stopping, and nothing left to answer
        auto job = std::move(jobs_.front());
        jobs_.pop_front();
        lock.unlock();
        job();
        lock.lock();
    }
}

// ---------------------------------------------------------------------------------------------

LoginLimiter::LoginLimiter(Settings settings, SteadyClock clock) : settings_(settings), clock_(std::move(clock)) {}

std::chrono::steady_clock::time_point LoginLimiter::now() const { return now_from(clock_); }

std::optional<std::chrono::seconds> LoginLimiter::wait_for(const std::string& address) const {
    const auto at = now();
    std::lock_guard lock(mutex_);
    auto it = records_.find(address);
    if (it == records_.end() || it->second.blocked_until <= at) return std::nullopt;
    // Rounded up: "Retry-After: 0" would invite the client straight back.
    return std::chrono::ceil<std::chrono::seconds>(it->second.blocked_until - at);
}

std::optional<std::chrono::seconds> LoginLimiter::failed(const std::string& address) {
    const auto at = now();
    std::lock_guard lock(mutex_);
    std::erase_if(records_, [&](const auto& entry) { return at - entry.second.last > std::chrono::hours(24); });
    if (records_.size() >= settings_.max_addresses && records_.count(address) == 0) {
        auto quietest = std::min_element(records_.begin(), records_.end(),
                                         [](const auto& a, const auto& b) { return a.second.last < b.second.last; });
        records_.erase(quietest);
    }
    Record& record = records_[address];
    record.last = at;
    ++record.failures;
    if (record.failures < settings_.free_failures) return std::nullopt;
    // The fifth failure waits first_delay, each one after twice as long as the one before.
    const unsigned doublings = std::min(record.failures - settings_.free_failures, 20u);
    const std::chrono::seconds delay =
        std::min<std::chrono::seconds>(settings_.first_delay * (std::int64_t{1} << doublings), settings_.longest_delay);
    record.blocked_until = at + delay;
    return std::chrono::duration_cast<std::chrono::seconds>(delay);
}

void LoginLimiter::succeeded(const std::string& address) {
    std::lock_guard lock(mutex_);
    records_.erase(address);
}

// ---------------------------------------------------------------------------------------------

std::optional<LoginForm> parse_login_body(std::string_view body, std::string_view content_type) {
    const std::string_view type = trimmed(content_type.substr(0, content_type.find(';')));
    const auto is = [&](std::string_view expected) {
        return type.size() == expected.size() && std::equal(type.begin(), type.end(), expected.begin(), [](char a, char b) {
                   return std::tolower(static_cast<unsigned char>(a)) == b;
               });
    };
    LoginForm form;
    if (is("application/json") || (type.empty() && trimmed(body).starts_with('{'))) {
        const auto json = nlohmann::json::parse(body, nullptr, false);
        if (json.is_discarded() || !json.is_object()) return std::nullopt;
        const auto user = json.find("user");
        const auto password = json.find("password");
        if (user == json.end() || password == json.end() || !user->is_string() || !password->is_string()) return std::nullopt;
        form.user = user->get<std::string>();
        form.password = password->get<std::string>();
    } else if (is("application/x-www-form-urlencoded") || type.empty()) {
        const auto values = parse_query(body);
        const auto user = values.find("user");
        const auto password = values.find("password");
        if (user == values.end() || password == values.end()) return std::nullopt;
        form.user = user->second;
        form.password = password->second;
    } else {
        return std::nullopt;
    }
    if (form.user.empty() || form.user.size() > 64 || form.password.size() > 1024) return std::nullopt;
    return form;
}

std::optional<std::string> cookie_value(std::string_view header, std::string_view name) {
    // RFC 6265, 5.4: "name=value" pairs separated by "; ".
    while (!header.empty()) {
        const auto semicolon = header.find(';');
        const std::string_view pair = trimmed(header.substr(0, semicolon));
        header = semicolon == std::string_view::npos ? std::string_view() : header.substr(semicolon + 1);
        const auto equals = pair.find('=');
        if (equals == std::string_view::npos) continue;
        if (trimmed(pair.substr(0, equals)) != name) continue;
        std::string_view value = trimmed(pair.substr(equals + 1));
        if (value.size() >= 2 && value.front() == '"' && value.back() == '"') value = value.substr(1, value.size() - 2);
        return std::string(value);
    }
    return std::nullopt;
}

}  // namespace loopwire::gateway
