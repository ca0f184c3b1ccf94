// The dashboard's assets when the dashboard itself is not part of the build: one page saying so
// and pointing at the API, which works without it.
#include "gateway/dashboard_assets.hpp"

namespace loopwire::gateway {
namespace {

constexpr std::string_view index_html = R"html(<!doctype html>
<html lang="en">
<head><meta charset="utf-8"><title>loopwire gateway</title></head>
<body>
<h1>loopwire gateway</h1>
<p>The dashboard is not part of this build. The HTTP API answers:</p>
<ul>
<li><a href="/api/devices">/api/devices</a>: the devices and their status</li>
<li>/api/devices/NAME: one device's parameters and values</li>
<li>/api/events: the changes, as server-sent events</li>
<li><a href="/metrics">/metrics</a>: the lines' and devices' figures for Prometheus</li>
</ul>
</body>
</html>
)html";

constexpr StaticAsset assets[] = {
    {"/index.html", "text/html; charset=utf-8", index_html},
};

}  // namespace

std::span<const StaticAsset> dashboard_assets() { return assets; }

}  // namespace loopwire::gateway
