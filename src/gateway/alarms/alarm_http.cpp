#include "gateway/alarms/alarm_http.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/peer_text.hpp"
#include "common/text_parsing.hpp"
#include "gateway/history_schema.hpp"
#include "gateway/http_json.hpp"
#include "gateway/http_text.hpp"

namespace loopwire::gateway::alarms {
namespace {

using Json = nlohmann::ordered_json;
constexpr std::string_view prefix = "/api/alarms";

HttpResponse error(unsigned status, const std::string& message) { return json_error(status, message); }

HttpOutcome now(HttpResponse response) { return {std::move(response), {}, {}}; }

HttpOutcome not_allowed(const std::string& allowed) { return now(method_not_allowed(allowed)); }

Json optional_number(const std::optional<double>& value) { return value ? Json(*value) : Json(nullptr); }

Json view_json(const AlarmView& view) {
    const bool ever = view.since != Time{};
    return Json{{"alarm", view.id},
                {"device", view.device},
                {"name", view.name},
                {"parameter", view.parameter},
                {"kind", view.kind},
                {"state", name_of(view.state)},
                {"since", ever ? Json(iso_time(view.since)) : Json(nullptr)},
                {"value", optional_number(view.value)},
                {"unit", view.unit},
                {"severity", name_of(view.severity)},
                {"message", view.message},
                {"shelved_until", view.shelved_until ? Json(iso_time(*view.shelved_until)) : Json(nullptr)}};
}

HttpOutcome current(const AlarmService& alarms) {
    Json list = Json::array();
    for (const AlarmView& view : alarms.views()) list.push_back(view_json(view));
    return now(json_response(200, Json{{"alarms", list}}));
}

HttpOutcome journal(const HttpRequest& request, const AlarmService& alarms, const HistorySource* history) {
    if (alarms.database().empty()) {
        return now(error(404, "no [history] configured: the alarm journal is kept in the history file; add a [history] "
                              "table to the gateway's configuration"));
    }
    auto query = audit_query(request.query, std::chrono::system_clock::now());
    if (!query) return now(error(400, query.error().message));
    auto read = [database = alarms.database(), query = *query](const HttpResponder& respond) {
        auto db = history::open_for_reading(database);
        if (!db) return respond(error(503, db.error().message));
        auto rows = read_journal(*db, query.from, query.to, query.limit);
        if (!rows) return respond(error(503, rows.error().message));
        HttpResponse response;
        response.headers.emplace_back("Cache-Control", "no-store");
        response.body = journal_json(*rows);
        respond(std::move(response));
    };
    // On the history reader's thread, as a history query: never on the network's.
    return {{}, [history, read](HttpResponder respond) {
                if (history) {
                    history->run_blocking([read, respond = std::move(respond)] { read(respond); });
                } else {
                    read(respond);
                }
            }, {}};
}

std::optional<AlarmAction> action_named(std::string_view name) {
    if (name == "ack") return AlarmAction::acknowledge;
    if (name == "shelve") return AlarmAction::shelve;
    if (name == "unshelve") return AlarmAction::unshelve;
    if (name == "out-of-service") return AlarmAction::remove_from_service;
    if (name == "in-service") return AlarmAction::return_to_service;
    return std::nullopt;
}

std::string text_field(const Json& body, const char* key) {
    const auto found = body.find(key);
    return found != body.end() && found->is_string() ? found->get<std::string>() : std::string();
}

HttpOutcome act(const HttpRequest& request, AlarmService& alarms, const std::string& id, AlarmAction action,
                const AlarmAuthorizer& authorize) {
    AlarmActor actor = authorize(request, action);
    if (actor.refusal) return now(std::move(*actor.refusal));
    Json body = Json::object();
    if (!request.body.empty()) {
        body = Json::parse(request.body, nullptr, false);
        if (body.is_discarded() || !body.is_object()) {
            return now(error(400, "expected a JSON object, e.g. {\"comment\": \"seen, operator on the way\"}"));
        }
    }
    std::string user = actor.user.empty() ? text_field(body, "user") : actor.user;
    if (user.empty()) user = "api";
    std::chrono::milliseconds duration{0};
    if (action == AlarmAction::shelve) {
        const std::string text = text_field(body, "duration");
        if (text.empty()) return now(error(400, "a shelving needs its duration, e.g. {\"duration\": \"1h\"}"));
        auto parsed = parse_period(text, "duration");
        if (!parsed) return now(error(400, parsed.error().message));
        duration = std::chrono::duration_cast<std::chrono::milliseconds>(*parsed);
    }
    const auto outcome = alarms.act(action, id, user, text_field(body, "comment"), duration);
    if (outcome.unknown) return now(error(404, fmt::format("no alarm \"{}\" (GET /api/alarms lists them)", id)));
    if (!outcome.refusal.empty()) return now(error(409, outcome.refusal));
    for (const AlarmView& view : alarms.views()) {
        if (view.id == id) return now(json_response(200, view_json(view)));
    }
    return now(json_response(200, Json::object()));
}

}  // namespace

std::optional<HttpOutcome> alarm_route(const HttpRequest& request, AlarmService* alarms, const HistorySource* history,
                                       const AlarmAuthorizer& authorize) {
    const std::string& path = request.path;
    if (path.rfind(prefix, 0) != 0) return std::nullopt;
    const std::string_view rest = std::string_view(path).substr(prefix.size());
    if (!rest.empty() && rest.front() != '/') return std::nullopt;
    if (!alarms) return now(error(404, "this gateway has no alarms"));
    const bool get = request.method == "GET" || request.method == "HEAD";
    if (rest.empty() || rest == "/") return get ? current(*alarms) : not_allowed("GET, HEAD");
    if (rest == "/history") return get ? journal(request, *alarms, history) : not_allowed("GET, HEAD");
    const auto slash = rest.rfind('/');
    const auto action = slash > 0 ? action_named(rest.substr(slash + 1)) : std::nullopt;
    auto id = slash > 0 ? percent_decode(rest.substr(1, slash - 1)) : std::nullopt;
    if (!action || !id || id->empty()) {
        return now(error(404, fmt::format("no such resource: {} (POST /api/alarms/DEVICE.ALARM/ack, /shelve, /unshelve, "
                                          "/out-of-service or /in-service)", printable_excerpt(path))));
    }
    if (request.method != "POST") return not_allowed("POST");
    return act(request, *alarms, *id, *action, authorize);
}

}  // namespace loopwire::gateway::alarms
