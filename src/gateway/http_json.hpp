#pragma once
// The HTTP API's JSON answers, for every route that answers one (http_api.cpp, the alarms').
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/peer_text.hpp"
#include "gateway/http_server.hpp"

namespace loopwire::gateway {

// Never cached. Replaced, not thrown on: a device's text is the device's, and a client's (a name
// in a path, a value in a body) the client's; either may not be valid UTF-8.
inline HttpResponse json_response(unsigned status, const nlohmann::ordered_json& body) {
    HttpResponse response;
    response.status = status;
    response.body = json_text(body);
    response.headers.emplace_back("Cache-Control", "no-store");
    return response;
}

// {"error": MESSAGE}
inline HttpResponse json_error(unsigned status, const std::string& message) {
    return json_response(status, nlohmann::ordered_json{{"error", message}});
}

// 405, with the Allow header.
inline HttpResponse method_not_allowed(const std::string& allowed) {
    HttpResponse response = json_error(405, fmt::format("method not allowed here (allowed: {})", allowed));
    response.headers.emplace_back("Allow", allowed);
    return response;
}

}  // namespace loopwire::gateway
