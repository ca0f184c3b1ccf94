#pragma once
// The HTTP API's alarm routes (gateway/http_api.hpp routes /api/alarms here):
//   GET  /api/alarms                     every alarm: state, since, value, unit, severity, message
//   GET  /api/alarms/history?from=&to=   the journal, newest first (&limit=, as /api/audit's)
//   POST /api/alarms/NAME/ack            {"comment": "..."}; NAME as "DEVICE.ALARM"
//   POST /api/alarms/NAME/shelve         {"duration": "1h", "comment": "..."}
//   POST /api/alarms/NAME/unshelve, /out-of-service, /in-service
// An action needs what a write needs (the caller's `authorize`, one function so the rule can change
// in one place); its user is the one `authorize` names, else the body's "user".
#include <functional>
#include <optional>
#include <string>

#include "gateway/alarms/alarm_service.hpp"
#include "gateway/history_source.hpp"
#include "gateway/http_server.hpp"

namespace loopwire::gateway::alarms {

struct AlarmActor {
    std::optional<HttpResponse> refusal;  // set: the request may not act
    std::string user;                     // who acts, when the front knows; else the body's "user"
};
using AlarmAuthorizer = std::function<AlarmActor(const HttpRequest&, AlarmAction)>;

// None: not an alarm route.
std::optional<HttpOutcome> alarm_route(const HttpRequest& request, AlarmService* alarms, const HistorySource* history,
                                       const AlarmAuthorizer& authorize);

}  // namespace loopwire::gateway::alarms
