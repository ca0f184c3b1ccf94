#include "gateway/http_api.hpp"

#include "gateway/alarms/alarm_http.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <map>
#include <optional>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "client/device_status.hpp"
#include "client/monitor_state.hpp"
#include "client/resolved_value.hpp"
#include "common/fnv1a.hpp"
#include "common/peer_text.hpp"
#include "gateway/dashboard_assets.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/http_sessions.hpp"
#include "gateway/http_json.hpp"
#include "gateway/http_text.hpp"
#include "gateway/metrics.hpp"
#include "profile/value_format.hpp"

namespace loopwire::gateway {
namespace {

using Json = nlohmann::ordered_json;

HttpResponse error(unsigned status, const std::string& message) { return json_error(status, message); }

HttpResponse not_allowed(const std::string& allowed) { return method_not_allowed(allowed); }

// A limit as the view has it, else the name of the parameter that sets it (not read yet), else null.
Json limit_json(const std::optional<double>& limit, const std::optional<device::Bound>& bound) {
    if (limit) return *limit;
    if (auto name = device::bounding_parameter(bound)) return Json{{"parameter", *name}};
    return nullptr;
}

Json value_json(const device::EngineeringValue& value) {
    return std::visit(
        [](const auto& v) -> Json {
            using T = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<T, std::monostate>) {
                return nullptr;
            } else if constexpr (std::is_same_v<T, std::map<std::string, bool>>) {
                Json bits = Json::object();
                for (const auto& [name, on] : v) bits[name] = on;
                return bits;
            } else {
                return v;
            }
        },
        value.value);
}

Json change_json(const ValueChange& change) {
    Json out{{"device", change.device}, {"parameter", change.parameter}};
    out["value"] = change.value ? value_json(*change.value) : Json(nullptr);
    out["text"] = change.text;
    out["unit"] = change.unit;
    out["status"] = change.status;
    out["error"] = change.error;
    out["time"] = iso_time(change.sampled);
    return out;
}

// The ETag of an asset: a hash of its bytes (FNV-1a), so it changes exactly when they do.
std::string etag_of(std::string_view body) { return fmt::format("\"{:016x}\"", fnv1a(body)); }

// Compares without stopping at the first difference, so the time taken says nothing of how much
// of a guessed token was right.
bool same_token(std::string_view given, std::string_view token) {
    unsigned char differ = given.size() == token.size() ? 0 : 1;
    for (std::size_t i = 0; i < given.size(); ++i) {
        differ |= static_cast<unsigned char>(given[i] ^ token[i % std::max<std::size_t>(token.size(), 1)]);
    }
    return differ == 0;
}

std::string lower_case(std::string_view text) {
    std::string lower(text);
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); });
    return lower;
}

// The name of a Host header without its port, in lower case: "[::1]:8080" -> "[::1]",
// "Gateway.Local" -> "gateway.local". None when it is not uri-host [":" port] (RFC 7230, 5.4).
std::optional<std::string> host_name_of(std::string_view host) {
    std::string_view name = host;
    std::string_view port;
    if (host.starts_with('[')) {
        const auto close = host.find(']');
        if (close == std::string_view::npos) return std::nullopt;
        name = host.substr(0, close + 1);
        port = host.substr(close + 1);
    } else if (const auto colon = host.rfind(':'); colon != std::string_view::npos) {
        name = host.substr(0, colon);
        port = host.substr(colon);
    }
    if (!port.empty() && (port.size() < 2 || port.size() > 6 || port.front() != ':' ||
                          !std::all_of(port.begin() + 1, port.end(), [](char c) { return c >= '0' && c <= '9'; }))) {
        return std::nullopt;
    }
    if (name.empty()) return std::nullopt;
    return lower_case(name);
}

// A failed history query: the asker's fault (400), or the historian's, unreachable or too slow
// (503: the same request may well succeed later).
unsigned history_failure_status(const Error& failure) {
    return failure.kind == ErrorKind::link || failure.kind == ErrorKind::timeout ? 503u : 400u;
}

// The answer to a write: what was written, or why not, with a status that fits.
HttpResponse write_response(const Result<WrittenValues>& written) {
    if (!written) {
        const Error& failure = written.error();
        // The device's mode (AC20 in local: Note 5) is a state to change first: a conflict.
        const bool mode = failure.message.find("can be written only in") != std::string::npos;
        const unsigned status = failure.kind == ErrorKind::timeout || failure.kind == ErrorKind::link ? 504u
                                : mode                                                              ? 409u
                                                                                                    : 422u;
        return error(status, failure.message);
    }
    Json values = Json::object();
    for (const auto& [parameter, text] : written->values) values[parameter] = text;
    return json_response(200, Json{{"written", values}});
}

// Whether `client` (as the server writes it: "127.0.0.1", "::1") is on a loopback address.
bool loopback_client(std::string_view client) { return client.starts_with("127.") || client == "::1"; }

// What logins share with the checks that run off the network thread (PasswordChecks): a check
// lets go of it after it has answered, which may be after the API has gone. The checks' thread
// itself is the API's (HttpApi::State::checks), joined when the API goes, never by a check.
struct Logins {
    Logins(std::shared_ptr<HttpLogins> kept, std::function<void(const std::string&)> warn)
        : state(std::move(kept)), sessions(state->sessions), limiter(state->limiter), log(std::move(warn)) {}
    std::shared_ptr<HttpLogins> state;
    SessionStore& sessions;
    LoginLimiter& limiter;
    std::function<void(const std::string&)> log;
    // A hash checked for a user name that has no password, so that a wrong name takes as long
    // as a wrong password and the time does not tell which names exist. Made on the checks'
    // thread when first needed.
    std::string unknown_user_hash;
};

// Who sent a request: a session's user (cookie), a machine's (bearer token), the token_file's
// holder ("token", an admin), or nobody.
struct Caller {
    bool known = false;
    std::string user;
    Role role = Role::viewer;
    std::optional<Session> session;
};

std::string session_cookie_header(const std::string& id, bool tls) {
    return fmt::format("{}={}; Path=/; HttpOnly; SameSite=Strict{}", session_cookie, id, tls ? "; Secure" : "");
}

struct ConfiguredDevice {
    std::string name;
    std::string line;
    device::DeviceAddress address;
    std::vector<const device::Parameter*> polled;
};

}  // namespace

struct HttpApi::State {
    std::string gateway_name;  // [gateway] name
    std::vector<ConfiguredDevice> devices;
    HttpApiSources sources;
    std::string token;        // empty: writes refused
    bool reads_need_token = false;
    std::vector<HttpUser> users;  // none: the token alone (and reads as reads_need_token says)
    HttpConfig::OpenReads open_reads = HttpConfig::OpenReads::loopback;
    bool tls = false;
    std::shared_ptr<Logins> logins;  // with users
    std::unique_ptr<PasswordChecks> checks;  // with users
    std::vector<std::string> hosts;  // the Host names answered, in lower case
    struct Asset {
        const StaticAsset* asset;
        std::string etag;
    };
    std::map<std::string, Asset, std::less<>> assets;

    const ConfiguredDevice* find(const std::string& name) const {
        for (const auto& device : devices) {
            if (device.name == name) return &device;
        }
        return nullptr;
    }

    std::optional<CachedDevice> cached(const std::string& name) const {
        for (auto& device : sources.cache->snapshot()) {
            if (device.name == name) return std::move(device);
        }
        return std::nullopt;
    }

    // None when the request may go on; else the refusal.
    std::optional<HttpResponse> check_token(const HttpRequest& request) const {
        constexpr std::string_view bearer = "Bearer ";
        const std::string& given = request.authorization;
        if (given.size() <= bearer.size() || !std::equal(bearer.begin(), bearer.end(), given.begin(),
                                                         [](char a, char b) { return std::tolower(a) == std::tolower(b); })) {
            HttpResponse refusal = error(401, "this needs the gateway's token: send the header \"Authorization: Bearer TOKEN\" "
                                              "with the token of the file [http] token_file names");
            refusal.headers.emplace_back("WWW-Authenticate", "Bearer");
            return refusal;
        }
        if (!same_token(std::string_view(given).substr(bearer.size()), token)) {
            HttpResponse refusal = error(401, "wrong token (it is the first line of the file [http] token_file names)");
            refusal.headers.emplace_back("WWW-Authenticate", "Bearer error=\"invalid_token\"");
            return refusal;
        }
        return std::nullopt;
    }

    // Who sent the request, or the refusal of credentials that are wrong (an unknown bearer
    // token). A session that has expired is nobody: reads may still be open.
    std::optional<HttpResponse> identify(const HttpRequest& request, Caller& caller) const {
        if (!request.authorization.empty()) {
            constexpr std::string_view bearer = "Bearer ";
            const std::string& given = request.authorization;
            const bool is_bearer = given.size() > bearer.size() &&
                                   std::equal(bearer.begin(), bearer.end(), given.begin(),
                                              [](char a, char b) { return std::tolower(a) == std::tolower(b); });
            const std::string_view presented = is_bearer ? std::string_view(given).substr(bearer.size()) : std::string_view();
            if (is_bearer && !token.empty() && same_token(presented, token)) {
                caller = {true, "token", Role::admin, std::nullopt};
                return std::nullopt;
            }
            if (is_bearer && !users.empty()) {
                const std::string hash = machine_token_hash(presented);
                for (const auto& user : users) {
                    if (user.machine() && same_secret(hash, user.hash)) {
                        caller = {true, user.name, user.role, std::nullopt};
                        return std::nullopt;
                    }
                }
            }
            HttpResponse refusal = error(401, "wrong token: send \"Authorization: Bearer TOKEN\" with a token `loopwire passwd "
                                              "--token` made, or the first line of the file [http] token_file names");
            refusal.headers.emplace_back("WWW-Authenticate", "Bearer error=\"invalid_token\"");
            return refusal;
        }
        if (logins) {
            if (auto id = cookie_value(request.cookie, session_cookie)) {
                if (auto session = logins->sessions.find(*id)) caller = {true, session->user, session->role, std::move(session)};
            }
        }
        return std::nullopt;
    }

    bool reads_open_to(const HttpRequest& request) const {
        switch (open_reads) {
            case HttpConfig::OpenReads::all: return true;
            case HttpConfig::OpenReads::none: return false;
            case HttpConfig::OpenReads::loopback: return loopback_client(request.client);
        }
        return false;
    }

    static HttpResponse login_needed() {
        HttpResponse refusal = error(401, "log in first (POST /api/login with user and password), or send \"Authorization: "
                                          "Bearer TOKEN\"");
        refusal.headers.emplace_back("WWW-Authenticate", "Bearer");
        return refusal;
    }

    // None when `caller` may write at all (known; over a session, with its CSRF token); else the
    // refusal. What the role may write is check_roles', once the names are known (and audited).
    std::optional<HttpResponse> check_writer(const HttpRequest& request, const Caller& caller) const {
        if (!caller.known) return login_needed();
        if (caller.session && !same_secret(request.csrf_token, caller.session->csrf)) {
            return error(403, "a write over a login session needs the header X-CSRF-Token with the session's token (the "
                              "\"csrf\" of POST /api/login's or GET /api/session's answer)");
        }
        return std::nullopt;
    }

    // Why `caller` may not write one of `assignments` (its role is below the one the parameter
    // needs, gateway/http_users.hpp); none when it may, or when there are no users. A name the
    // profile does not resolve to one parameter is left for the writer to refuse.
    std::optional<std::string> check_roles(const ConfiguredDevice& device, const std::vector<WriteAssignment>& assignments,
                                           const Caller& caller) const {
        if (users.empty()) return std::nullopt;
        if (caller.role == Role::viewer) {
            return fmt::format("user \"{}\" is a viewer, who reads but does not write; an operator writes set points and "
                               "modes, an admin every parameter",
                               caller.user);
        }
        const device::Profile& profile = *device.address.profile;
        for (const auto& assignment : assignments) {
            auto resolved = device::resolve_parameters(profile, {assignment.parameter});
            if (!resolved || resolved->size() != 1) continue;
            const device::Parameter& parameter = *resolved->front();
            if (role_may_write(caller.role, profile, parameter)) continue;

            return fmt::format("user \"{}\" is an {} and may not write \"{}\": {} writes it", caller.user,
                               role_name(caller.role), parameter.name, role_name(role_to_write(profile, parameter)) == "admin"
                                                                           ? "only an admin (it is the device's configuration, "
                                                                             "not a set point or mode)"
                                                                           : "an operator or admin");
        }
        return std::nullopt;
    }

    HttpOutcome login(const HttpRequest& request) const;
    HttpOutcome logout(const HttpRequest& request, const Caller& caller) const;
    HttpResponse session_answer(const HttpRequest& request, const Caller& caller) const;

    // None when the Host header names this gateway; else the refusal. A browser sends the name
    // from its address bar: a page of another site whose name an attacker points at this
    // address (DNS rebinding) sends that other name, and is not answered.
    std::optional<HttpResponse> check_host(const HttpRequest& request) const {
        if (request.host.empty()) {
            return error(400, "the request has no Host header (HTTP/1.1 requires one, RFC 7230 5.4)");
        }
        const auto name = host_name_of(request.host);
        if (name && std::find(hosts.begin(), hosts.end(), *name) != hosts.end()) return std::nullopt;
        const std::string shown = name ? quoted_excerpt(*name) : quoted_excerpt(request.host);
        return error(421, fmt::format("this gateway does not answer to the host name {} (it answers to {}); if that is a "
                                      "name it is reached by, add it to the configuration's [http] hosts list, e.g. "
                                      "hosts = [\"gateway.plant.local\"]",
                                      shown, fmt::join(hosts, ", ")));
    }

    // Who may act on an alarm (acknowledge, shelve, ...): whoever may write, with the same token.
    // Who acts on an alarm. With users: an operator acknowledges; shelving and taking out of
    // service (hiding an alarm for a while) are an admin's, as ISA-18.2 gives them to whoever
    // is responsible for the alarm system, not to whoever is on shift. Over a session, with its
    // CSRF token as for every write.
    alarms::AlarmActor alarm_actor(const HttpRequest& request, const Caller& caller, alarms::AlarmAction action) const {
        if (!users.empty()) {
            if (auto refusal = check_writer(request, caller)) return {std::move(refusal), {}};
            const bool acknowledge = action == alarms::AlarmAction::acknowledge;
            if (caller.role == Role::viewer || (!acknowledge && caller.role != Role::admin)) {
                return {error(403, fmt::format("{} (role {}) may not {}: {}", caller.user, role_name(caller.role),
                                               acknowledge ? "acknowledge alarms" : "shelve alarms or take them out of service",
                                               acknowledge ? "operators and admins may" : "admins may")),
                        {}};
            }
            return {std::nullopt, caller.user};
        }
        if (token.empty()) {
            return {error(403, "alarm actions over HTTP are off: give the gateway a token with [http] token_file = \"FILE\" "
                               "and send it as \"Authorization: Bearer TOKEN\""),
                    {}};
        }
        return {check_token(request), {}};
    }

    HttpOutcome route(const HttpRequest& request);
    HttpResponse devices_list() const;
    HttpResponse device_detail(const ConfiguredDevice& device) const;
    HttpOutcome write(const ConfiguredDevice& device, const HttpRequest& request, const Caller& caller) const;
    HttpOutcome events(const HttpRequest& request) const;
    HttpOutcome history(const HttpRequest& request) const;
    HttpOutcome history_gateways() const;
    HttpOutcome audit(const HttpRequest& request) const;
    HttpResponse metrics() const;
    HttpResponse asset(const HttpRequest& request) const;
};

HttpApi::HttpApi(const GatewayConfig& config, HttpApiSources sources) : state_(std::make_unique<State>()) {
    for (const auto& line : config.lines) {
        for (const auto& device : line.devices) {
            state_->devices.push_back({device.name, line.name, device.address, polled_parameters(device)});
        }
    }
    state_->sources = std::move(sources);
    const HttpConfig http = config.http.value_or(HttpConfig{});
    state_->token = http.token;
    state_->reads_need_token = !http.loopback();
    state_->users = http.users;
    state_->open_reads = http.open_reads;
    state_->tls = !http.certificate.empty();
    if (!http.users.empty()) {
        auto kept = state_->sources.logins ? state_->sources.logins : std::make_shared<HttpLogins>();
        kept->sessions.set_idle_timeout(http.session_timeout);
        kept->sessions.keep_only(http.users);
        state_->logins = std::make_shared<Logins>(std::move(kept), state_->sources.log);
        state_->checks = std::make_unique<PasswordChecks>();
    }
    state_->gateway_name = config.name;
    state_->hosts = {"localhost", "127.0.0.1", "[::1]"};
    const std::string listen = lower_case(http.host.find(':') != std::string::npos ? "[" + http.host + "]" : http.host);
    for (const auto& name : http.hosts) state_->hosts.push_back(name);
    if (std::find(state_->hosts.begin(), state_->hosts.end(), listen) == state_->hosts.end()) state_->hosts.push_back(listen);
    for (const StaticAsset& asset : dashboard_assets()) {
        state_->assets[std::string(asset.path)] = {&asset, etag_of(asset.body)};
    }
}

HttpApi::~HttpApi() = default;

HttpOutcome HttpApi::handle(const HttpRequest& request) { return state_->route(request); }

HttpOutcome HttpApi::State::route(const HttpRequest& request) {
    if (auto refusal = check_host(request)) return {*refusal, {}, {}};
    const std::string& path = request.path;
    const bool get = request.method == "GET";
    // The server answers HEAD as GET without the body (http_server.hpp).
    static const std::string readable = "GET, HEAD";
    const bool api = path.rfind("/api/", 0) == 0 || path == "/metrics";
    Caller caller;
    if (users.empty()) {
        if (api && reads_need_token) {
            // Not on loopback: everyone on the network could read otherwise.
            if (auto refusal = check_token(request)) return {*refusal, {}, {}};
        }
    } else if (api) {
        if (auto refusal = identify(request, caller)) return {*refusal, {}, {}};
        if (path == "/api/login") return request.method == "POST" ? login(request) : HttpOutcome{not_allowed("POST"), {}, {}};
        if (path == "/api/logout") return request.method == "POST" ? logout(request, caller) : HttpOutcome{not_allowed("POST"), {}, {}};
        if (path == "/api/session") return {get ? session_answer(request, caller) : not_allowed(readable), {}, {}};
        if (!caller.known && !reads_open_to(request)) return {login_needed(), {}, {}};
    }
    if (path == "/api/login" || path == "/api/logout" || path == "/api/session") {
        return {error(404, "there are no logins: the configuration names no [http] users_file"), {}, {}};
    }
    if (path == "/api/devices") return {get ? devices_list() : not_allowed(readable), {}, {}};
    if (path == "/api/events") return get ? events(request) : HttpOutcome{not_allowed(readable), {}, {}};
    if (path == "/api/history") return get ? history(request) : HttpOutcome{not_allowed(readable), {}, {}};
    if (path == "/api/audit") return get ? audit(request) : HttpOutcome{not_allowed(readable), {}, {}};
    if (auto answered = alarms::alarm_route(request, sources.alarms, sources.history,
                                            [this, &caller](const HttpRequest& asking, alarms::AlarmAction action) {
                                                return alarm_actor(asking, caller, action);
                                            })) {
        return std::move(*answered);
    }
    if (path == "/api/history/gateways") return get ? history_gateways() : HttpOutcome{not_allowed(readable), {}, {}};
    if (path == "/metrics") return {get ? metrics() : not_allowed(readable), {}, {}};
    constexpr std::string_view prefix = "/api/devices/";
    if (path.rfind(prefix, 0) == 0) {
        std::string rest = path.substr(prefix.size());
        constexpr std::string_view write_suffix = "/write";
        const bool is_write = rest.size() > write_suffix.size() &&
                              rest.compare(rest.size() - write_suffix.size(), write_suffix.size(), write_suffix) == 0;
        if (is_write) rest.resize(rest.size() - write_suffix.size());
        auto name = percent_decode(rest);
        if (!name || name->empty() || name->find('/') != std::string::npos) {
            return {error(404, fmt::format("no such resource: {}", path)), {}, {}};
        }
        const ConfiguredDevice* device = find(*name);
        if (!device) return {error(404, fmt::format("no device \"{}\" on this gateway (GET /api/devices lists them)", *name)), {}, {}};
        if (is_write) return request.method == "POST" ? write(*device, request, caller) : HttpOutcome{not_allowed("POST"), {}, {}};
        return {get ? device_detail(*device) : not_allowed(readable), {}, {}};
    }
    if (!api && (path == "/" || assets.count(path) != 0)) return {get ? asset(request) : not_allowed(readable), {}, {}};
    return {error(404, fmt::format("no such resource: {} (the API is under /api/: devices, events, history, audit, alarms; and /metrics)", path)),
            {}, {}};
}

HttpResponse HttpApi::State::devices_list() const {
    Json list = Json::array();
    const auto snapshot = sources.cache->snapshot();
    for (const auto& device : devices) {
        auto cached = std::find_if(snapshot.begin(), snapshot.end(), [&](const CachedDevice& c) { return c.name == device.name; });
        list.push_back(Json{{"name", device.name},
                            {"device", device.address.profile->id},
                            {"title", device.address.profile->title},
                            {"line", device.line},
                            {"unit", device.address.unit},
                            {"status", device::status_text(cached != snapshot.end() ? cached->state.status
                                                                                    : device::DeviceStatus::waiting)}});
    }
    return json_response(200, list);
}

HttpResponse HttpApi::State::device_detail(const ConfiguredDevice& device) const {
    const auto cached = this->cached(device.name);
    const device::Profile& profile = *device.address.profile;
    Json out{{"name", device.name}, {"device", profile.id}, {"title", profile.title}, {"line", device.line},
             {"unit", device.address.unit}};
    out["status"] = device::status_text(cached ? cached->state.status : device::DeviceStatus::waiting);
    out["error"] =
        cached && cached->state.status != device::DeviceStatus::ok ? cached->state.last_error : std::string();
    out["sampled"] = cached ? Json(iso_time(cached->sampled)) : Json(nullptr);
    Json groups = Json::array();
    Json parameters = Json::array();
    for (const device::Parameter& parameter : profile.parameters) {
        const device::WatchedValue* watched = nullptr;
        if (cached) {
            for (const auto& value : cached->state.values) {
                if (value.parameter == &parameter) watched = &value;
            }
        }
        const bool polled = std::find(device.polled.begin(), device.polled.end(), &parameter) != device.polled.end();
        if (parameter.hidden && !polled) continue;
        if (std::find(groups.begin(), groups.end(), parameter.group) == groups.end()) groups.push_back(parameter.group);
        // The resolved view every front shows (client/resolved_value.hpp): the unit as the device
        // is configured (a TC10's °C or °F), the limits as it holds them, the status, and the
        // age as of the cache's view, on the clock the polls run on.
        const device::EngineeringValue* last = watched && watched->last ? &*watched->last : nullptr;
        // A parameter not polled still has its limits from the words the polls read.
        const auto resolved = watched ? resolved_view(*cached, *watched)
                                      : device::resolve_value(parameter, nullptr, cached ? cached->state.known : device::RawValues{});
        Json p{{"name", parameter.name}, {"mnemonic", parameter.mnemonic}, {"group", parameter.group},
               {"description", parameter.description}, {"unit", resolved.unit}, {"polled", polled}};
        p["value"] = last ? value_json(*last) : Json(nullptr);
        p["text"] = resolved.text;
        // A polled parameter not in the cache yet waits for its device's first poll.
        p["status"] = watched ? resolved.status
                              : std::string(polled ? device::status_text(device::DeviceStatus::waiting) : "not-polled");
        p["age"] = resolved.age ? Json(*resolved.age) : Json(nullptr);
        p["error"] = watched ? resolved.error : std::string();
        p["readable"] = parameter.readable;
        p["writable"] = parameter.writable;
        // In engineering units as the device holds them (what a write is checked against), with
        // the one fallback every front shows (device::ResolvedValue::limits); null while not known.
        const auto& limits = resolved.limits;
        p["min"] = limit_json(limits.min, parameter.min);
        p["max"] = limit_json(limits.max, parameter.max);
        // Fixed min/max still in display counts: the decimal point that scales them is not known.
        if (parameter.range_in_counts && !limits.min && !limits.max) p["range_counts"] = true;
        if (const auto* fixed = std::get_if<int>(&parameter.decimals)) {
            p["decimals"] = *fixed;
        } else {
            p["decimals"] = Json{{"parameter", std::get<std::string>(parameter.decimals)}};
        }
        if (!parameter.enum_labels.empty()) {
            Json labels = Json::object();
            for (const auto& [raw, label] : parameter.enum_labels) labels[std::to_string(raw)] = label;
            p["enum"] = labels;
        }
        if (!parameter.write_modes.empty()) p["write_modes"] = parameter.write_modes;
        parameters.push_back(std::move(p));
    }
    // The profile's PV, SP, OUT (and other) aliases: which values the dashboard shows first.
    out["aliases"] = profile.aliases;
    out["groups"] = std::move(groups);
    out["parameters"] = std::move(parameters);
    return json_response(200, out);
}

namespace {

// A JSON number that is not an integer in plain decimal digits, as the profile's checks read
// numbers: dump() writes 1e+308 or 1e-08, which they would refuse as "not a number" instead of
// saying what is wrong with the value (out of range, too many decimals). The shortest digits
// that read back as the same double (std::to_chars, fixed).
std::string fixed_text(double value) {
    std::array<char, 400> text{};  // the largest double has 309 digits before the point
    const auto written = std::to_chars(text.data(), text.data() + text.size(), value, std::chars_format::fixed);
    return std::string(text.data(), written.ptr);
}

// A value to write as the CLI would take it: a string as it is ("150", "manual"), a number as
// its shortest text (Node-RED and scripts send 150 or 0.85, not "150"); the profile's checks then
// refuse what the parameter cannot take (too many decimals, out of range). Anything else is not
// a value.
Result<std::string> written_text(const nlohmann::json& value) {
    if (value.is_string()) return value.get<std::string>();
    if (value.is_number_float()) return fixed_text(value.get<double>());
    if (value.is_number()) return value.dump();
    return make_error(ErrorKind::usage, fmt::format("expected a number or a string as it would be typed (150, \"on\"), "
                                                    "not {}", value.type_name()));
}

}  // namespace

HttpOutcome HttpApi::State::write(const ConfiguredDevice& device, const HttpRequest& request, const Caller& caller) const {
    if (!users.empty()) {
        if (auto refusal = check_writer(request, caller)) return {*refusal, {}, {}};
    } else if (token.empty()) {
        return {error(403, "writes over HTTP are off: give the gateway a token with [http] token_file = \"FILE\" (a file "
                           "readable by the gateway alone whose first line is the token), then send it as "
                           "\"Authorization: Bearer TOKEN\""),
                {}, {}};
    }
    if (users.empty()) {
        if (auto refusal = check_token(request)) return {*refusal, {}, {}};
    }
    const auto body = nlohmann::json::parse(request.body, nullptr, false);
    if (body.is_discarded()) {
        return {error(400, "the body is not JSON; send an object of parameter names and values, e.g. "
                           "{\"set_point\": 150} or {\"mode\": \"manual\"}"),
                {}, {}};
    }
    if (!body.is_object() || body.empty()) {
        return {error(400, "expected a JSON object of parameter names and values, e.g. {\"set_point\": 150} or "
                           "{\"mode\": \"manual\"}"),
                {}, {}};
    }
    const WriteOrigin origin{"http", request.client, users.empty() ? std::string() : caller.user};
    std::vector<WriteAssignment> assignments;
    for (const auto& [name, value] : body.items()) {
        auto text = written_text(value);
        if (!text) {
            const std::string why = fmt::format("the value of \"{}\": {}", name, text.error().message);
            sources.writer->audit_refusal(device.name, {{name, value.dump(-1, ' ', false, Json::error_handler_t::replace)}},
                                          origin, why);
            return {error(400, why), {}, {}};
        }
        assignments.push_back({name, std::move(*text)});
    }
    if (auto refusal = check_roles(device, assignments, caller)) {
        sources.writer->audit_refusal(device.name, assignments, origin, *refusal);
        return {error(403, *refusal), {}, {}};
    }
    // The writer's policy, answered as what it is: the device cannot take writes now (it does not
    // answer, or its line is down), so nothing was sent and the same write may go later.
    if (auto silent = sources.writer->refusal(device.name)) {
        sources.writer->audit_refusal(device.name, assignments, origin, silent->message);
        HttpResponse refused = error(503, silent->message);
        refused.headers.emplace_back("Retry-After", "5");
        return {std::move(refused), {}, {}};
    }
    // Handed to the device's line; answered from its completion once the line has answered,
    // so a write waiting for a slow line holds up no other client and no other line.
    auto deferred = [writer = sources.writer, name = device.name, assignments = std::move(assignments),
                     origin](HttpResponder respond) {
        const bool queued = writer->write_async(
            name, assignments, [respond](Result<WrittenValues> written) { respond(write_response(written)); }, origin);
        if (!queued) {
            HttpResponse busy = error(503, fmt::format("the line of device \"{}\" has too many writes waiting; nothing was "
                                                       "sent, write again later", name));
            busy.headers.emplace_back("Retry-After", "1");
            respond(std::move(busy));
        }
    };
    return {{}, std::move(deferred), {}};
}

HttpOutcome HttpApi::State::events(const HttpRequest& request) const {
    const auto query = parse_query(request.query);
    std::string only;
    if (auto it = query.find("device"); it != query.end()) {
        if (!find(it->second)) return {error(404, fmt::format("no device \"{}\" on this gateway", it->second)), {}, {}};
        only = it->second;
    }
    auto start = [cache = sources.cache, only](EventSender send) {
        return cache->subscribe([send = std::move(send), only](const ValueChange& change) {
            if (!only.empty() && change.device != only) return;
            send(fmt::format("data: {}\n\n", json_text(change_json(change))));
        });
    };
    return {{}, {}, std::move(start)};
}

HttpResponse HttpApi::State::metrics() const {
    std::vector<MetricsDevice> names;
    for (const auto& device : devices) names.push_back({device.name, device.line});
    HttpResponse response;
    response.content_type = "text/plain; version=0.0.4; charset=utf-8";
    const std::optional<FrontReport> front = sources.front ? std::optional(sources.front()) : std::nullopt;
    const HttpReport http{sources.http_not_allowed ? sources.http_not_allowed() : 0};
    const std::optional<OpcuaFigures> opcua = sources.opcua ? std::optional(sources.opcua()) : std::nullopt;
    response.body = prometheus_text(gateway_name, sources.lines(), names, sources.cache->snapshot(), sources.history,
                                    front ? &*front : nullptr, &http, opcua ? &*opcua : nullptr);
    if (sources.alarms) response.body += alarms::alarm_metrics(sources.alarms->views());
    response.headers.emplace_back("Cache-Control", "no-store");
    return response;
}

HttpResponse HttpApi::State::asset(const HttpRequest& request) const {
    const std::string path = request.path == "/" ? "/index.html" : request.path;
    auto it = assets.find(path);
    if (it == assets.end()) {
        return error(404, "the dashboard is not part of this build (the API answers under /api/)");
    }
    HttpResponse response;
    // Revalidated each time: a new build's dashboard is seen at once, an unchanged one costs 304.
    response.headers.emplace_back("ETag", it->second.etag);
    response.headers.emplace_back("Cache-Control", "no-cache");
    if (request.if_none_match == it->second.etag) {
        response.status = 304;
        response.content_type = std::string(it->second.asset->content_type);
        return response;
    }
    response.content_type = std::string(it->second.asset->content_type);
    response.body = std::string(it->second.asset->body);
    return response;
}

namespace {

HttpResponse history_reply(const ParsedHistoryQuery& query, const Result<std::vector<HistorySeries>>& series) {
    if (!series) return error(history_failure_status(series.error()), series.error().message);
    HttpResponse response;
    response.headers.emplace_back("Cache-Control", "no-store");
    if (query.csv) {
        response.content_type = "text/csv; charset=utf-8";
        response.body = history_csv(*series);
        return response;
    }
    Json list = Json::array();
    for (const auto& one : *series) {
        Json buckets = Json::array();
        for (const auto& bucket : one.buckets) {
            buckets.push_back(Json{{"time", iso_time(bucket.start)}, {"min", bucket.min}, {"max", bucket.max},
                                   {"mean", bucket.mean}, {"count", bucket.count}});
        }
        Json gaps = Json::array();
        for (const auto& gap : one.gaps) {
            gaps.push_back(Json{{"from", iso_time(gap.start)}, {"to", gap.end ? Json(iso_time(*gap.end)) : Json(nullptr)}});
        }
        // The value in force at `from` (recorded before it and holding there), null when none is
        // known: where a chart's line starts, left out of the buckets' statistics.
        Json before = one.before ? Json{{"time", iso_time(one.before->time)}, {"value", one.before->value}} : Json(nullptr);
        list.push_back(Json{{"parameter", one.parameter}, {"unit", one.unit}, {"before", std::move(before)},
                            {"buckets", std::move(buckets)}, {"gaps", std::move(gaps)}});
    }
    return json_response(200, Json{{"device", query.query.device}, {"from", iso_time(query.query.from)},
                                   {"to", iso_time(query.query.to)}, {"series", std::move(list)}});
}

// The query runs where it may block (HistorySource::run_blocking, the history reader's thread), not on
// the loop the API serves on: a month of history, or a historian slow to answer, holds up no
// poll and no other client. What it captures outlives the server, which waits for the answer.
HttpOutcome deferred_history(const HistorySource& history, ParsedHistoryQuery query) {
    return {{}, [&history, query = std::move(query)](HttpResponder respond) {
                history.run_blocking([&history, query, respond = std::move(respond)] {
                    respond(history_reply(query, history.query(query.query)));
                });
            }, {}};
}

}  // namespace

HttpOutcome HttpApi::State::history(const HttpRequest& request) const {
    if (!sources.history) {
        return {error(404, "no [history] configured: add a [history] table to the gateway's configuration to record values"),
                {}, {}};
    }
    auto query = history_query(request.query, std::chrono::system_clock::now());
    if (!query) return {error(400, query.error().message), {}, {}};
    const ConfiguredDevice* device = find(query->query.device);
    // Another gateway's device (gateway=NAME) is not configured here: the historian, which
    // knows its parameters, takes the aliases among them, and refuses a name unknown there.
    if (!query->query.gateway.empty() && query->query.gateway != gateway_name) {
        return deferred_history(*sources.history, std::move(*query));
    }
    if (!device) {
        return {error(404, fmt::format("no device \"{}\" on this gateway (GET /api/devices lists them)", query->query.device)),
                {}, {}};
    }
    // Named as the CLI names them: an alias (PV, SP, OUT) or a mnemonic stands for its
    // parameter; a name the profile does not know is left for the store to refuse.
    for (auto& name : query->query.parameters) {
        auto resolved = device::resolve_parameters(*device->address.profile, {name});
        if (resolved && resolved->size() == 1) name = resolved->front()->name;
    }
    return deferred_history(*sources.history, std::move(*query));
}

// The audit of writes, newest first, from the history file: read on the history reader's
// thread, as a history query is.
HttpOutcome HttpApi::State::audit(const HttpRequest& request) const {
    if (!sources.history) {
        return {error(404, "no [history] configured: the audit of writes is kept in the history file; add a [history] "
                           "table to the gateway's configuration"),
                {}, {}};
    }
    auto query = audit_query(request.query, std::chrono::system_clock::now());
    if (!query) return {error(400, query.error().message), {}, {}};
    if (!query->device.empty() && !find(query->device)) {
        return {error(404, fmt::format("no device \"{}\" on this gateway (GET /api/devices lists them)", query->device)), {}, {}};
    }
    return {{}, [history = sources.history, query = std::move(*query)](HttpResponder respond) {
                history->run_blocking([history, query, respond = std::move(respond)] {
                    auto records = history->audit(query);
                    if (!records) return respond(error(history_failure_status(records.error()), records.error().message));
                    HttpResponse response;
                    response.headers.emplace_back("Cache-Control", "no-store");
                    response.body = audit_json(*records);
                    respond(std::move(response));
                });
            }, {}};
}

// The gateways whose history the historian holds, for the dashboard's choice of whose trend
// to show; 404 when there is no historian ([history] forward_to absent). Asked on the
// history reader's thread, as a query is.
HttpOutcome HttpApi::State::history_gateways() const {
    if (!sources.history) {
        return {error(404, "no [history] configured: add a [history] table to the gateway's configuration to record values"),
                {}, {}};
    }
    return {{}, [history = sources.history, name = gateway_name](HttpResponder respond) {
                history->run_blocking([history, name, respond = std::move(respond)] {
                    auto names = history->historian_gateways();
                    if (!names) {
                        const unsigned status = names.error().kind == ErrorKind::usage ? 404u : history_failure_status(names.error());
                        return respond(error(status, names.error().message));
                    }
                    HttpResponse response = json_response(200, Json{{"this", name}, {"gateways", *names}});
                    response.headers.emplace_back("Cache-Control", "no-store");
                    respond(std::move(response));
                });
            }, {}};
}

}  // namespace loopwire::gateway
namespace loopwire::gateway {

// The login's check runs on the checks' thread (Argon2id is slow on purpose); a client whose
// failures are over the limit is refused at once, with the wait, never held in the handler.
HttpOutcome HttpApi::State::login(const HttpRequest& request) const {
    if (auto wait = logins->limiter.wait_for(request.client)) {
        HttpResponse refusal = error(429, fmt::format("too many failed logins from {}: try again in {} s", request.client,
                                                      wait->count()));
        refusal.headers.emplace_back("Retry-After", std::to_string(wait->count()));
        return {std::move(refusal), {}, {}};
    }
    auto form = parse_login_body(request.body, request.content_type);
    if (!form) {
        return {error(400, "expected the user and password: JSON {\"user\": \"NAME\", \"password\": \"...\"} or a form "
                           "user=NAME&password=..."),
                {}, {}};
    }
    std::string hash;
    Role role = Role::viewer;
    for (const auto& user : users) {
        if (user.name == form->user && !user.machine()) {
            hash = user.hash;
            role = user.role;
        }
    }
    auto check = [logins = logins, checks = checks.get(), form = std::move(*form), hash, role, client = request.client,
                  tls = tls](HttpResponder respond) {
        const bool posted = checks->post([logins, form, hash, role, client, tls, respond] {
            bool right = false;
            if (hash.empty()) {
                if (logins->unknown_user_hash.empty()) {
                    auto made = hash_password("unknown user");
                    if (made) logins->unknown_user_hash = std::move(*made);
                }
                verify_password(form.password, logins->unknown_user_hash);
            } else {
                right = verify_password(form.password, hash);
            }
            if (!right) {
                const auto wait = logins->limiter.failed(client);
                if (logins->log) {
                    logins->log(fmt::format("{}http: failed login as {} from {}{}", gateway_warning_prefix,
                                            quoted_excerpt(form.user), client,
                                            wait ? fmt::format(" (its logins wait {} s)", wait->count()) : std::string()));
                }
                HttpResponse refusal = error(401, "wrong user name or password");
                if (wait) refusal.headers.emplace_back("Retry-After", std::to_string(wait->count()));
                return respond(std::move(refusal));
            }
            logins->limiter.succeeded(client);
            const Session session = logins->sessions.open(form.user, role);
            HttpResponse answer = json_response(200, Json{{"user", session.user}, {"role", role_name(role)}, {"csrf", session.csrf}});
            answer.headers.emplace_back("Set-Cookie", session_cookie_header(session.id, tls));
            respond(std::move(answer));
        });
        if (!posted) {
            HttpResponse busy = error(503, "too many logins are being checked; try again in a second");
            busy.headers.emplace_back("Retry-After", "1");
            respond(std::move(busy));
        }
    };
    return {{}, std::move(check), {}};
}

HttpOutcome HttpApi::State::logout(const HttpRequest& request, const Caller& caller) const {
    if (caller.session) {
        if (!same_secret(request.csrf_token, caller.session->csrf)) {
            return {error(403, "logging out needs the header X-CSRF-Token with the session's token"), {}, {}};
        }
        logins->sessions.close(caller.session->id);
    }
    HttpResponse answer = json_response(200, Json{{"logged_out", caller.session.has_value()}});
    answer.headers.emplace_back("Set-Cookie", fmt::format("{}=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0{}", session_cookie,
                                                          tls ? "; Secure" : ""));
    return {std::move(answer), {}, {}};
}

// Who is logged in, for the dashboard: 401 when nobody (then `open_reads` says whether it may
// show the values without a login).
HttpResponse HttpApi::State::session_answer(const HttpRequest& request, const Caller& caller) const {
    if (!caller.known) {
        HttpResponse refusal = json_response(401, Json{{"error", "not logged in (POST /api/login)"},
                                                       {"open_reads", reads_open_to(request)}});
        return refusal;
    }
    Json body{{"user", caller.user}, {"role", role_name(caller.role)}};
    if (caller.session) body["csrf"] = caller.session->csrf;
    return json_response(200, body);
}

}  // namespace loopwire::gateway
