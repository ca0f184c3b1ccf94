// The HTTP front's request path (gateway/http_server.hpp parse_http_request, then
// gateway/http_api.hpp's router) on arbitrary bytes, without sockets: a gateway with a TC10 on a
// line whose master fails every request at once, with a token. Properties: it never throws or
// aborts; bytes that form a request are answered, each response a status 100..599 whose JSON
// body (when it is JSON) parses; a refusal of the parser is 400, 413, 431 or 501 (a
// Transfer-Encoding other than chunked); a deferred write is
// answered exactly once; an event stream starts and stops.
#include <atomic>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "dead_line_master.hpp"
#include "fuzz_support.hpp"
#include "gateway/device_writer.hpp"
#include "gateway/engine.hpp"
#include "gateway/gateway_config.hpp"
#include "gateway/http_api.hpp"
#include "gateway/http_server.hpp"
#include "gateway/line_scheduler.hpp"
#include "gateway/value_cache.hpp"

using namespace loopwire;

namespace {

constexpr const char* plant = R"toml(
[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200"

[[lines.devices]]
name = "oven"
device = "tc10@3"

[modbus_tcp]
enabled = false

[http]
listen = "127.0.0.1:8080"
hosts = ["gateway.plant.local"]
)toml";

struct Front {
    std::shared_ptr<session::Master> master = std::make_shared<fuzz::DeadLineMaster>();
    std::shared_ptr<gateway::LineScheduler> line = std::make_shared<gateway::LineScheduler>(master);
    gateway::ValueCache cache;
    gateway::Engine engine;  // the writer's loop: goes after it
    std::unique_ptr<gateway::DeviceWriter> writer;
    std::unique_ptr<gateway::HttpApi> api;
    gateway::HttpServerSettings settings;

    Front() {
        auto profiles = device::ProfileRegistry::builtins();
        fuzz::check(profiles.ok(), "the built-in profiles load");
        auto config = gateway::parse_gateway_config(plant, "fuzz.toml", *profiles);
        fuzz::check(config.ok(), "the fuzz plant parses");
        config->http->token = "fuzz-token-0123456789";  // as if read from token_file: writes are open
        const auto& oven = config->lines.front().devices.front();
        writer = std::make_unique<gateway::DeviceWriter>(engine, std::vector<gateway::WritableDevice>{{oven.name, oven.address, line}},
                                                         std::chrono::milliseconds(1000));
        gateway::HttpApiSources sources;
        sources.cache = &cache;
        sources.writer = writer.get();
        sources.lines = [] { return std::vector<gateway::LineReport>{}; };
        api = std::make_unique<gateway::HttpApi>(*config, std::move(sources));
        settings.header_limit = 2048;
        settings.body_limit = 1024;
    }
};

Front& front() {
    static Front* instance = new Front();  // never destroyed: libFuzzer exits without unwinding
    return *instance;
}

void check_response(const gateway::HttpResponse& response) {
    fuzz::check(response.status >= 100 && response.status <= 599, "a response has an HTTP status");
    if (response.content_type == "application/json" && !response.body.empty()) {
        fuzz::check(!nlohmann::json::parse(response.body, nullptr, false).is_discarded(), "a JSON body parses");
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    Front& f = front();
    const std::string_view bytes(reinterpret_cast<const char*>(data), size);
    const auto parsed = gateway::parse_http_request(bytes, f.settings);
    fuzz::check(!(parsed.request && parsed.refusal), "a request or a refusal, not both");
    if (parsed.refusal) {
        const unsigned status = parsed.refusal->status;
        fuzz::check(status == 400 || status == 413 || status == 431 || status == 501,
                    "the parser refuses with 400, 413, 431 or 501");
        check_response(*parsed.refusal);
    }
    if (!parsed.request) return 0;
    gateway::HttpOutcome outcome = f.api->handle(*parsed.request);
    if (outcome.deferred) {
        std::atomic<int> answers{0};
        std::optional<gateway::HttpResponse> response;
        std::atomic<bool> done{false};
        outcome.deferred([&](gateway::HttpResponse answer) {
            if (answers.fetch_add(1) == 0) response = std::move(answer);
            done.store(true);
        });
        // The dead line answers at once; the writer thread responds shortly.
        while (!done.load()) std::this_thread::yield();
        fuzz::check(answers.load() == 1, "deferred work is answered once");
        check_response(*response);
    } else if (outcome.events) {
        auto subscription = outcome.events([](const std::string& event) {
            fuzz::check(event.starts_with("data: ") && event.ends_with("\n\n"), "an event is one data line");
        });
        subscription.reset();
    } else {
        check_response(outcome.response);
    }
    return 0;
}
