#include "gateway/opcua/opcua_server.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <cstdarg>
#include <cstdio>
#include <cerrno>
#include <cstring>
#include <deque>
#include <future>
#include <map>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <open62541/plugin/accesscontrol_default.h>
#include <open62541/server.h>
#include <open62541/server_config_default.h>

#include "gateway/opcua/opcua_nodes.hpp"

namespace loopwire::gateway {
namespace {

// How long a Write waits for the device's answer. The writer always answers (its own limit
// for a write waiting for its line is 10 s, then the line's timeout and retries); past this the
// client hears Bad_Timeout and the audit still records what the device said.
constexpr std::chrono::seconds write_wait{30};
// How often the front's thread wakes at the least to take the value changes queued for it.
constexpr double apply_every_ms = 50;

// Binds `port` on `host` (0: any free one) and lets it go: the port the kernel gave, or why not.
// open62541 1.4 neither says which port it took for 0 nor fails its startup when it cannot
// listen (it logs and serves nothing), so the gateway asks first and says so itself.
Result<std::uint16_t> try_port(const std::string& host, std::uint16_t wanted) {
    const bool ipv6 = host.find(':') != std::string::npos;
    const int fd = ::socket(ipv6 ? AF_INET6 : AF_INET, SOCK_STREAM, 0);
    if (fd < 0) return make_error(ErrorKind::link, std::strerror(errno));
    const int on = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);  // as a listener after a restart
    sockaddr_storage address{};
    socklen_t length = 0;
    if (ipv6) {
        auto* in6 = reinterpret_cast<sockaddr_in6*>(&address);
        in6->sin6_family = AF_INET6;
        in6->sin6_port = htons(wanted);
        if (::inet_pton(AF_INET6, host.c_str(), &in6->sin6_addr) != 1) in6->sin6_addr = in6addr_any;
        length = sizeof(sockaddr_in6);
    } else {
        auto* in4 = reinterpret_cast<sockaddr_in*>(&address);
        in4->sin_family = AF_INET;
        in4->sin_port = htons(wanted);
        if (::inet_pton(AF_INET, host.c_str(), &in4->sin_addr) != 1) in4->sin_addr.s_addr = htonl(INADDR_ANY);
        length = sizeof(sockaddr_in);
    }
    Result<std::uint16_t> port = make_error(ErrorKind::link, "");
    if (::bind(fd, reinterpret_cast<sockaddr*>(&address), length) != 0 || ::listen(fd, 1) != 0 ||
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
        port = make_error(ErrorKind::link, std::strerror(errno));
    } else {
        port = ntohs(ipv6 ? reinterpret_cast<sockaddr_in6*>(&address)->sin6_port : reinterpret_cast<sockaddr_in*>(&address)->sin_port);
    }
    ::close(fd);
    return port;
}

// open62541's errors go to the gateway's log; its chatter below that does not (its warnings at
// start are about the certificate authentication this endpoint does not offer).
void log_to_gateway(void* context, UA_LogLevel level, UA_LogCategory, const char* message, va_list args) {
    if (level < UA_LOGLEVEL_ERROR) return;
    char text[512];
    std::vsnprintf(text, sizeof text, message, args);
    (*static_cast<GatewayLog*>(context))(fmt::format("opcua: {}", text));
}

std::string node_text(const UA_NodeId* id) {
    UA_String text = UA_STRING_NULL;
    UA_NodeId_print(id, &text);
    std::string out(reinterpret_cast<const char*>(text.data), text.length);
    UA_String_clear(&text);
    return out;
}

}  // namespace

struct OpcuaServer::State {
    OpcuaConfig config;
    const DeviceWriter* writer = nullptr;
    GatewayLog log;
    UA_Logger logger{};
    UA_Server* server = nullptr;
    std::uint16_t port = 0;
    // The address space's values, owned by the front's thread once it runs (deques: the nodes
    // hold pointers to them).
    std::deque<OpcuaVariable> variables;
    std::deque<OpcuaDeviceStatus> statuses;
    std::map<std::string, OpcuaVariable*> by_name;  // "device.parameter"
    std::map<std::string, OpcuaDeviceStatus*> status_of;
    // The changes the cache told, waiting for the front's thread.
    std::mutex queue_mutex;
    std::vector<ValueChange> queued;
    ValueSubscription subscription;
    std::atomic<bool> stopping{false};
    // Whether the address space is built: open62541 may write a node's first value as it adds
    // it, which must never reach a device.
    bool built = false;
    std::thread thread;
    std::atomic<std::uint64_t> sessions{0};
    std::atomic<std::uint64_t> monitored_items{0};
    std::atomic<std::uint64_t> writes_confirmed{0};
    std::atomic<std::uint64_t> writes_refused{0};

    bool started = false;  // UA_Server_run_startup succeeded: shut down before deleting

    ~State() {
        subscription.reset();  // first: nothing more is queued
        stopping = true;
        if (thread.joinable()) thread.join();
        if (server) {
            if (started) UA_Server_run_shutdown(server);
            UA_Server_delete(server);
        }
        for (auto& variable : variables) UA_Variant_clear(&variable.value);
    }

    void queue(const ValueChange& change) {
        std::lock_guard lock(queue_mutex);
        queued.push_back(change);
    }

    // On the front's thread, between its iterations: never inside one of open62541's callbacks,
    // so writing the properties takes the server's lock freely.
    void apply_queued() {
        std::vector<ValueChange> changes;
        {
            std::lock_guard lock(queue_mutex);
            changes.swap(queued);
        }
        for (const ValueChange& change : changes) apply(change);
        sessions = UA_Server_getStatistics(server).ss.currentSessionCount;
    }

    void apply(const ValueChange& change) {
        if (change.about_device()) {
            auto found = status_of.find(change.device);
            if (found == status_of.end()) return;
            found->second->word = change.status;
            found->second->error = change.error;
            found->second->source_time = ua_time(change.sampled);
            return;
        }
        auto found = by_name.find(change.device + "." + change.parameter);
        if (found == by_name.end()) return;
        show(server, *found->second, {change.value, change.text, change.unit, change.limits, change.status, change.sampled});
    }

    void run() {
        while (!stopping) {
            apply_queued();
            UA_Server_run_iterate(server, true);
        }
    }

    // A Write, on the front's thread: refused at once when it cannot be taken, else handed to the
    // device's line and answered with the device's answer.
    UA_StatusCode write(OpcuaVariable& variable, const UA_NodeId* session, const UA_DataValue& value) {
        const WriteOrigin origin{"opcua", node_text(session), ""};
        if (!value.hasValue) return refuse(UA_STATUSCODE_BADTYPEMISMATCH, variable, origin, "", "no value given");
        auto text = write_text(variable, value.value);
        if (!text) return refuse(UA_STATUSCODE_BADTYPEMISMATCH, variable, origin, "", "a value of another type than the variable's");
        const auto number = write_number(value.value);
        const auto& limits = variable.limits;
        if (number && ((limits.min && *number < *limits.min) || (limits.max && *number > *limits.max))) {
            return refuse(UA_STATUSCODE_BADOUTOFRANGE, variable, origin, *text,
                          fmt::format("{} is outside {}..{}", *text, limits.min ? fmt::format("{}", *limits.min) : "",
                                      limits.max ? fmt::format("{}", *limits.max) : ""));
        }
        if (auto refusal = writer->refusal(variable.device)) {
            return refuse(write_error_code(*refusal, true), variable, origin, *text, refusal->message);
        }
        auto outcome = std::make_shared<std::promise<Result<WrittenValues>>>();
        auto answer = outcome->get_future();
        const bool queued_write = writer->write_async(
            variable.device, {{variable.parameter->name, *text}},
            [outcome](Result<WrittenValues> result) { outcome->set_value(std::move(result)); }, origin);
        if (!queued_write) return refuse(UA_STATUSCODE_BADTOOMANYOPERATIONS, variable, origin, *text, "busy: too many writes waiting");
        if (answer.wait_for(write_wait) != std::future_status::ready) {
            ++writes_refused;
            return UA_STATUSCODE_BADTIMEOUT;
        }
        auto result = answer.get();
        if (!result) {
            ++writes_refused;
            return write_error_code(result.error(), false);
        }
        ++writes_confirmed;
        return UA_STATUSCODE_GOOD;
    }

    UA_StatusCode refuse(UA_StatusCode code, const OpcuaVariable& variable, const WriteOrigin& origin, const std::string& text,
                         const std::string& reason) {
        ++writes_refused;
        writer->audit_refusal(variable.device, {{variable.parameter->name, text}}, origin, reason);
        return code;
    }
};

namespace {

UA_StatusCode read_variable(UA_Server*, const UA_NodeId*, void*, const UA_NodeId*, void* context, UA_Boolean source_time,
                            const UA_NumericRange*, UA_DataValue* value) {
    const auto& variable = *static_cast<const OpcuaVariable*>(context);
    if (variable.value.type) {
        UA_Variant_copy(&variable.value, &value->value);
        value->hasValue = true;
    }
    value->status = variable.status;
    value->hasStatus = variable.status != UA_STATUSCODE_GOOD;
    if (source_time && variable.source_time != 0) {
        value->sourceTimestamp = variable.source_time;
        value->hasSourceTimestamp = true;
    }
    return UA_STATUSCODE_GOOD;
}

UA_StatusCode read_status(UA_Server*, const UA_NodeId*, void*, const UA_NodeId*, void* context, UA_Boolean source_time,
                          const UA_NumericRange*, UA_DataValue* value) {
    const auto& status = *static_cast<const OpcuaDeviceStatus*>(context);
    UA_String word = UA_STRING(const_cast<char*>(status.word.c_str()));
    UA_Variant_setScalarCopy(&value->value, &word, &UA_TYPES[UA_TYPES_STRING]);
    value->hasValue = true;
    if (source_time && status.source_time != 0) {
        value->sourceTimestamp = status.source_time;
        value->hasSourceTimestamp = true;
    }
    return UA_STATUSCODE_GOOD;
}

UA_StatusCode write_variable(UA_Server*, const UA_NodeId* session, void*, const UA_NodeId*, void* context,
                             const UA_NumericRange* range, const UA_DataValue* value) {
    if (range) return UA_STATUSCODE_BADINDEXRANGEINVALID;
    auto& variable = *static_cast<OpcuaVariable*>(context);
    if (!static_cast<OpcuaServer::State*>(variable.owner)->built) return UA_STATUSCODE_GOOD;
    return static_cast<OpcuaServer::State*>(variable.owner)->write(variable, session, *value);
}

void monitored_item_registered(UA_Server* server, const UA_NodeId*, void*, const UA_NodeId*, void*, UA_UInt32, UA_Boolean removed) {
    auto* state = static_cast<OpcuaServer::State*>(UA_Server_getConfig(server)->context);
    if (removed) {
        --state->monitored_items;
    } else {
        ++state->monitored_items;
    }
}

// The endpoint's configuration: the listen address (open62541 listens on its serverUrls), the
// limits, who may connect, and the log.
UA_StatusCode configure(UA_ServerConfig& config, OpcuaServer::State& state) {
    state.logger = UA_Logger{log_to_gateway, &state.log, nullptr};
    config.logging = &state.logger;
    UA_StatusCode status = UA_ServerConfig_setMinimal(&config, state.port, nullptr);
    if (status != UA_STATUSCODE_GOOD) return status;
    config.context = &state;
    const OpcuaConfig& wanted = state.config;
    const bool ipv6 = wanted.host.find(':') != std::string::npos;
    const std::string url = fmt::format("opc.tcp://{}{}{}:{}", ipv6 ? "[" : "", wanted.host, ipv6 ? "]" : "", state.port);
    UA_Array_delete(config.serverUrls, config.serverUrlsSize, &UA_TYPES[UA_TYPES_STRING]);
    config.serverUrls = static_cast<UA_String*>(UA_Array_new(1, &UA_TYPES[UA_TYPES_STRING]));
    config.serverUrls[0] = UA_STRING_ALLOC(url.c_str());
    config.serverUrlsSize = 1;
    UA_String_clear(&config.applicationDescription.applicationUri);
    config.applicationDescription.applicationUri = UA_STRING_ALLOC(wanted.application_uri.c_str());
    UA_LocalizedText_clear(&config.applicationDescription.applicationName);
    config.applicationDescription.applicationName = UA_LOCALIZEDTEXT_ALLOC("", wanted.application_name.c_str());
    config.maxSessions = static_cast<UA_UInt16>(std::min<unsigned>(wanted.max_sessions, 65535));
    config.maxSubscriptions = wanted.max_subscriptions;
    config.maxMonitoredItems = wanted.max_monitored_items;
    config.monitoredItemRegisterCallback = monitored_item_registered;
    // No user list yet: anonymous = false leaves no way in, which --check's plan says.
    config.accessControl.clear(&config.accessControl);
    return UA_AccessControl_default(&config, wanted.anonymous, nullptr, 0, nullptr);
}

}  // namespace

OpcuaServer::OpcuaServer(std::unique_ptr<State> state) : state_(std::move(state)) {}
OpcuaServer::~OpcuaServer() = default;

Result<std::unique_ptr<OpcuaServer>> OpcuaServer::open(const OpcuaConfig& config, const std::string& gateway_name,
                                                       std::vector<OpcuaDevice> devices, const DeviceWriter& writer,
                                                       ValueCache& cache, GatewayLog log) {
    auto state = std::make_unique<State>();
    state->config = config;
    state->writer = &writer;
    state->log = log ? std::move(log) : GatewayLog([](const std::string&) {});
    auto port = try_port(config.host, config.port);
    if (!port) {
        return make_error(ErrorKind::link, fmt::format("[opcua] listen {}: cannot listen there: {} (another program on the port? "
                                                       "choose another, or 0 for any free one)",
                                                       config.listen, port.error().message));
    }
    state->port = *port;
    UA_ServerConfig server_config;
    std::memset(&server_config, 0, sizeof server_config);
    if (UA_StatusCode status = configure(server_config, *state); status != UA_STATUSCODE_GOOD) {
        UA_ServerConfig_clean(&server_config);
        return make_error(ErrorKind::usage, fmt::format("[opcua]: cannot configure the server: {}", UA_StatusCode_name(status)));
    }
    state->server = UA_Server_newWithConfig(&server_config);
    if (!state->server) return make_error(ErrorKind::link, "[opcua]: cannot create the server");
    UA_Server* server = state->server;

    const std::string root_name = gateway_name.empty() ? "loopwire" : gateway_name;
    const UA_NodeId objects = UA_NODEID_NUMERIC(0, UA_NS0ID_OBJECTSFOLDER);
    UA_StatusCode built = add_object(server, "gateway", objects, root_name, true);
    const UA_DataSource value_source{read_variable, write_variable};
    const UA_DataSource status_source{read_status, nullptr};
    std::map<std::string, bool> lines_added;
    for (const OpcuaDevice& device : devices) {
        const std::string line_id = "line:" + device.line;
        if (!lines_added[device.line]) {
            UA_NodeId gateway = string_node("gateway");
            built |= add_object(server, line_id, gateway, device.line, true);
            UA_NodeId_clear(&gateway);
            lines_added[device.line] = true;
        }
        UA_NodeId line = string_node(line_id);
        built |= add_object(server, device.name, line, device.name, false);
        UA_NodeId_clear(&line);
        UA_NodeId device_node = string_node(device.name);
        OpcuaDeviceStatus& status = state->statuses.emplace_back();
        status.device = device.name;
        status.node_id = device.name + "/status";
        state->status_of[device.name] = &status;
        built |= add_device_status(server, status, device_node, status_source);
        for (const device::Parameter* parameter : device.parameters) {
            OpcuaVariable& variable = state->variables.emplace_back();
            variable.device = device.name;
            variable.parameter = parameter;
            variable.kind = opcua_data_kind(*parameter);
            variable.writable = config.writes && parameter->writable;
            variable.owner = state.get();
            variable.node_id = device.name + "." + parameter->name;
            variable.unit = parameter->unit;
            // Good while the node is added: open62541 reads it then to check its type, and refuses
            // a node whose read fails. Waiting for its first poll from then on.
            variable.status = UA_STATUSCODE_GOOD;
            UA_Variant_setScalar(&variable.value, UA_new(data_type_of(variable.kind)), data_type_of(variable.kind));
            state->by_name[variable.node_id] = &variable;
            built |= add_variable(server, variable, device_node, value_source);
        }
        UA_NodeId_clear(&device_node);
    }
    for (auto& variable : state->variables) {
        variable.status = UA_STATUSCODE_BADWAITINGFORINITIALDATA;
        UA_Variant_clear(&variable.value);
    }
    state->built = true;
    if (built != UA_STATUSCODE_GOOD) {
        return make_error(ErrorKind::usage, fmt::format("[opcua]: cannot build the address space: {}", UA_StatusCode_name(built)));
    }
    UA_UInt64 wake_id = 0;
    UA_Server_addRepeatedCallback(server, [](UA_Server*, void*) {}, nullptr, apply_every_ms, &wake_id);
    if (UA_StatusCode started = UA_Server_run_startup(server); started != UA_STATUSCODE_GOOD) {
        return make_error(ErrorKind::link, fmt::format("[opcua] listen {}: cannot listen on port {}: {}", config.listen,
                                                       state->port, UA_StatusCode_name(started)));
    }
    state->started = true;
    State* running = state.get();
    state->subscription = cache.subscribe([running](const ValueChange& change) { running->queue(change); });
    state->thread = std::thread([running] {
        pthread_setname_np(pthread_self(), "lw-opcua");
        running->run();
    });
    return std::unique_ptr<OpcuaServer>(new OpcuaServer(std::move(state)));
}

std::uint16_t OpcuaServer::port() const { return state_->port; }

std::string OpcuaServer::endpoint() const {
    const bool ipv6 = state_->config.host.find(':') != std::string::npos;
    return fmt::format("opc.tcp://{}{}{}:{}", ipv6 ? "[" : "", state_->config.host, ipv6 ? "]" : "", state_->port);
}

OpcuaFigures OpcuaServer::figures() const {
    OpcuaFigures figures;
    figures.sessions = state_->sessions;
    figures.monitored_items = state_->monitored_items;
    figures.writes_confirmed = state_->writes_confirmed;
    figures.writes_refused = state_->writes_refused;
    return figures;
}

}  // namespace loopwire::gateway
