#pragma once
// The dashboard's files, built into the program: the HTTP server (gateway/http_server.hpp)
// serves them at GET / (the asset whose path is "/index.html") and GET /assets/*, so a gateway
// needs no files beside it. The build provides one implementation of dashboard_assets().
#include <span>
#include <string_view>

namespace loopwire::gateway {

struct StaticAsset {
    std::string_view path;          // "/index.html", "/assets/app.js"
    std::string_view content_type;  // "text/html; charset=utf-8"
    std::string_view body;
};

std::span<const StaticAsset> dashboard_assets();

}  // namespace loopwire::gateway
