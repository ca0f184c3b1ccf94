#include "gateway/gateway.hpp"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <thread>
#include <map>
#include <mutex>
#include <optional>
#include <set>

#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <fmt/format.h>

#include "devices/registry.hpp"
#include "gateway/engine.hpp"
#include "gateway/alarms/alarm_service.hpp"
#include "gateway/history_forwarder.hpp"
#include "gateway/history_reader.hpp"
#include "gateway/history_store.hpp"
#include "gateway/http_api.hpp"
#include "gateway/http_server.hpp"
#include "gateway/line_keeper.hpp"
#include "gateway/mqtt_bridge.hpp"
#include "gateway/opcua/opcua_server.hpp"
#include "gateway/sparkplug/sparkplug_node.hpp"
#include "session/line_loop.hpp"
#include "session/master.hpp"
#include "session/slave.hpp"
#include "simulation/simulated_lines.hpp"

namespace loopwire::gateway {
namespace {

// Carries the Modbus TCP front's "a client wrote to this device" to the polls
// (PollGroups::written_unknown), on the engine's loop. The forwarding units hold it weakly and may
// outlive the gateway (a kept front holds them until the next one is routed); close() is called
// before the polls go, and waits for a notice being posted, so none reaches them afterwards.
class FrontWriteNotices {
public:
    void open(Engine& engine, PollGroups& polls) {
        std::lock_guard lock(mutex_);
        engine_ = &engine;
        polls_ = &polls;
    }
    void close() {
        std::lock_guard lock(mutex_);
        engine_ = nullptr;
        polls_ = nullptr;
    }
    // On a line's thread.
    void written(const std::string& device) {
        std::lock_guard lock(mutex_);
        if (!engine_) return;
        // Posted before close(), so it runs before the polls' take-down (engine.hpp).
        boost::asio::post(engine_->loop(), [polls = polls_, device] { polls->written_unknown(device); });
    }

private:
    std::mutex mutex_;
    Engine* engine_ = nullptr;
    PollGroups* polls_ = nullptr;
};

// A virtual line's devices: each simulated from its profile, as `loopwire simulate` would.
session::UnitMap simulated_devices(const LineConfig& line) {
    device::SimulationEnvironment environment;
    environment.speed = line.simulation->speed;
    environment.seed = line.simulation->seed;
    session::UnitMap units;
    for (const DeviceConfig& device : line.devices) {
        const std::uint8_t unit = device.address.unit;
        units[unit] = device::models::make_simulated_device(
            device.address.profile, environment.on_line(unit, line.link));
    }
    return units;
}

// The bus of a virtual line with its simulated devices serving on it, from the lines' loop,
// which carries the masters too (created with the first).
Result<std::shared_ptr<transport::VirtualBus>> open_virtual_line(const LineConfig& line, const GatewayOptions& options,
                                                                 std::shared_ptr<simulation::SimulatedLines>& simulations,
                                                                 const std::shared_ptr<session::LineLoop>& line_loop) {
    auto bus = transport::VirtualBus::create(line.link.serial.baud, line.link.serial.bits_per_character());
    if (options.virtual_bus_faults) bus->set_fault_injector(options.virtual_bus_faults);
    if (!simulations) simulations = std::make_shared<simulation::SimulatedLines>(line_loop);
    auto served = simulations->add(bus->attach("simulated devices", transport::VirtualBus::Writes::return_at_once),
                                   std::make_unique<session::Slave>(line.link, simulated_devices(line)));
    if (!served) return served.error();
    return bus;
}

// How the line's master is opened, the first time and after each failure: the port or
// connection the link names, or a fresh attachment to the virtual line's bus.
Result<MasterOpener> line_opener(const LineConfig& line, const GatewayOptions& options,
                                 std::shared_ptr<simulation::SimulatedLines>& simulations,
                                 session::MasterOptions master_options) {
    if (!line.simulation) {
        return MasterOpener([link = line.link, master_options] { return session::open_master(link, master_options); });
    }
    auto bus = open_virtual_line(line, options, simulations, master_options.loop);
    if (!bus) return bus.error();
    return MasterOpener([bus = *bus, link = line.link, master_options]() -> Result<std::unique_ptr<session::Master>> {
        return session::make_serial_master(bus->attach("gateway"), link, master_options);
    });
}

// A line whose port cannot be opened now is not an error: it starts down and is reopened with
// back-off (gateway/reopening_master.hpp) while the other lines serve. Only a configuration the
// port can never take (ErrorKind::usage) is.
Result<OpenLine> open_line(const LineConfig& line, const GatewayOptions& options,
                           std::shared_ptr<simulation::SimulatedLines>& simulations,
                           const std::shared_ptr<session::LineLoop>& line_loop) {
    OpenLine opened{line, line.link.to_string(), std::make_shared<std::atomic<std::uint64_t>>(0), nullptr, nullptr};
    session::MasterOptions master_options;
    master_options.timeout = line.timeout;
    master_options.retries = line.retries;
    master_options.late_reply_window = line.late_reply_window;
    master_options.trace = options.trace;
    master_options.discarded = opened.garbled;
    // Every line is carried on the lines' shared loop: a serial framing's exchanges (a port, a
    // virtual line, RTU through a device server), and a Modbus TCP device's connection, read
    // there while requests are written from the engine. So no line costs a thread of its own.
    master_options.loop = line_loop;
    auto open = line_opener(line, options, simulations, std::move(master_options));
    if (!open) return open.error();
    opened.master = std::make_shared<ReopeningMaster>(line.name, opened.link, std::move(*open), ReopenSchedule{},
                                                      steady_clock(), options.log, LinkConcurrency::on_loop, line_loop);
    if (auto started = opened.master->start(); !started) return started.error();
    LineSchedulerOptions scheduling;
    scheduling.max_in_flight = line.max_in_flight;
    opened.scheduler = std::make_shared<LineScheduler>(opened.master, scheduling);
    return opened;
}

// Whether and where the history is forwarded ([history] forward_to).
std::optional<ForwardOptions> forward_options(const HistoryConfig& history, const GatewayConfig& config) {
    if (history.forward_to.empty()) return std::nullopt;
    ForwardOptions forward;
    forward.conninfo = history.forward_to;
    if (!history.password.empty()) forward.password = history.password;
    forward.gateway = config.name;
    return forward;
}

// A value's text and unit as the polls last read it, for the audit's old value of a write.
KnownValueLookup known_values(const ValueCache& cache) {
    return [&cache](const std::string& device, const std::string& parameter) -> std::optional<KnownValue> {
        for (const auto& cached : cache.snapshot()) {
            if (cached.name != device) continue;
            for (const auto& value : cached.state.values) {
                if (!value.parameter || value.parameter->name != parameter || !value.last) continue;
                const auto resolved = resolved_view(cached, value);
                return KnownValue{resolved.text, resolved.decimals, resolved.unit};
            }
        }
        return std::nullopt;
    };
}

// The history's three parts, each on its own thread and connection: the store writes the file,
// the forwarder ships the file's outbox to the historian, the reader answers the queries (of the
// file, and of other gateways' history in the historian). They start and stop here alone:
//   start: the store opens the file (sets it up), the forwarder and the reader open it after it;
//          the store is told of the forwarder, then its writer starts (open_history);
//   stop:  the reader first (it answers what is asked still, and reads the others' figures),
//          then the store (its writer's last commit tells the forwarder), the forwarder last.
struct History {
    History() = default;
    History(const History&) = delete;
    History& operator=(const History&) = delete;
    ~History() {
        // The writes audited from now on (a line finishing its last) go to the log alone.
        if (audit) audit->attach(nullptr);
        reader.reset();
        store.reset();
        forwarder.reset();
    }
    std::unique_ptr<HistoryForwarder> forwarder;  // none unless [history] forward_to
    // Written by the store's writer after each of its commits (also_write): goes after the store.
    std::unique_ptr<alarms::AlarmJournal> alarm_journal;
    std::unique_ptr<HistoryStore> store;
    std::unique_ptr<HistoryReader> reader;
    std::shared_ptr<WriteAudit> audit;  // given the store while both are there
};

// Another gateway's history for the HTTP API: from the historian this one forwards to, with a
// connect bounded for an asker that waits (an HTTP request), unlike the forwarder's.
HistorianAccess historian_access(const ForwardOptions& forward) {
    HistorianAccess access;
    access.conninfo = forward.conninfo;
    access.password = forward.password;
    access.limits.connect_timeout_seconds = std::min(forward.connect_timeout_seconds, access.limits.connect_timeout_seconds);
    return access;
}

// The history database, with every parameter the polls read declared as a series, and what
// forwards and reads it, started in order (History).
Result<std::unique_ptr<History>> open_history(const HistoryConfig& config, const GatewayConfig& gateway, const GatewayLog& log) {
    const std::optional<ForwardOptions> forward = forward_options(config, gateway);
    HistoryOptions options;
    options.database = config.database;
    options.keep = config.keep;
    options.heartbeat = config.heartbeat;
    options.log = log;
    options.outbox = forward.has_value();
    std::vector<HistorySeriesName> declared;
    for (const auto& line : gateway.lines) {
        for (const auto& device : line.devices) {
            for (const device::Parameter* parameter : polled_parameters(device)) {
                declared.push_back({device.name, parameter->name, parameter->unit});
            }
        }
    }
    auto history = std::make_unique<History>();
    auto store = HistoryStore::open(std::move(options), declared);
    if (!store) return store.error();
    history->store = std::move(*store);
    if (forward) {
        auto forwarder = HistoryForwarder::start(config.database, *forward, config.keep, {}, log);
        if (!forwarder) return forwarder.error();
        history->forwarder = std::move(*forwarder);
        history->store->on_outbox([forwarder = history->forwarder.get()](std::uint64_t rows, std::int64_t first_t) {
            forwarder->queued(rows, first_t);
        });
    }
    HistoryReaderOptions reading;
    reading.database = config.database;
    reading.heartbeat = config.heartbeat;
    reading.gateway = gateway.name;
    if (forward) reading.historian = historian_access(*forward);
    auto reader = HistoryReader::open(std::move(reading), *history->store, history->forwarder.get());
    if (!reader) return reader.error();
    history->reader = std::move(*reader);
    // The alarm journal's table in the same file, committed by the store's writer.
    auto journal = alarms::AlarmJournal::open(config.database, config.keep, log);
    if (!journal) return journal.error();
    history->alarm_journal = std::move(*journal);
    history->store->also_write([journal = history->alarm_journal.get()] { (void)journal->write_pending(); });
    history->store->start();
    return history;
}

LineReport report_of(const OpenLine& line);  // below

}  // namespace

// How long a write from a front (MQTT, HTTP) may wait for its line before it is given up.
constexpr std::chrono::milliseconds write_limit{10000};

struct Gateway::Parts {
    // A front kept by the caller (GatewayOptions::front) lends its loop to the engine: the
    // clients, the polls and the writes by name on one thread (gateway/modbus_tcp_front.hpp).
    Parts(ModbusTcpFront* kept_front, LineKeeper* line_keeper)
        : engine(kept_front ? std::make_unique<Engine>(kept_front->loop()) : std::make_unique<Engine>()),
          keeper(line_keeper),
          simulations(line_keeper ? line_keeper->simulations() : nullptr),
          line_loop(line_keeper ? line_keeper->loop() : std::make_shared<session::LineLoop>()) {}
    // Before any member goes: the notices, while the polls are still there; and the lines' masters,
    // so that a read under way ends now instead of holding the polls' stop (and with it a SIGTERM)
    // until its reply timeout passes. Its end is marked abandoned: no device is told anything.
    // A line handed over for a reload (hand_over_to) is not closed: its scheduler answers every
    // asker now instead, and the keeper holds it for the next gateway.
    ~Parts() {
        front_writes->close();
        for (std::size_t i = 0; i < lines.size(); ++i) {
            if (i < handed_over.size() && handed_over[i]) {
                lines[i].scheduler->hand_over();
                keeper->keep(lines[i]);
            } else {
                lines[i].master->close();
            }
        }
    }

    std::chrono::milliseconds statistics_interval{0};
    std::function<void()> alive;               // GatewayOptions::alive
    std::chrono::milliseconds alive_every{0};  // GatewayOptions::alive_every
    GatewayLog log;
    std::function<void(const std::stop_token&)> wait_for_stop;  // GatewayOptions::wait_for_stop
    std::function<bool()> http_listener_kept;                    // GatewayOptions::http_listener_kept
    std::shared_ptr<HttpLogins> http_logins;                     // GatewayOptions::http_logins
    // First, so it goes last: the polls, the writer and the statistics run on its loop and take
    // themselves down from it before they go.
    std::unique_ptr<Engine> engine;
    // The caller's, across reloads (GatewayOptions::lines); or none.
    LineKeeper* keeper = nullptr;
    std::vector<bool> handed_over;  // by line: kept for the next gateway (hand_over_to)
    // The simulated devices of the virtual lines, if any; after the lines have gone.
    std::shared_ptr<simulation::SimulatedLines> simulations;
    // The loop that carries the serial lines (session/line_loop.hpp); the lines' masters hold it
    // too, and it goes once they have.
    std::shared_ptr<session::LineLoop> line_loop;
    // Every write from every front is audited through it (write_audit.hpp); before the lines,
    // the units and the writer, so it outlives the writes they finish as they go.
    std::shared_ptr<WriteAudit> audit;
    // The front is destroyed first, then the polls (members go in reverse order): no request
    // reaches a line scheduler that is gone.
    std::vector<OpenLine> lines;
    ValueCache cache;
    // Before the polls, so destroyed after them: the last changes they find are written.
    std::unique_ptr<History> history;
    ValueSubscription history_subscription;
    // Fed by the cache, journaled in the history file, ticked on the engine's loop; gone before
    // the history and the cache, after the polls.
    std::unique_ptr<alarms::AlarmService> alarms;
    std::unique_ptr<PollGroups> polls;
    // Closed before the polls go (~Parts), which it posts to.
    std::shared_ptr<FrontWriteNotices> front_writes = std::make_shared<FrontWriteNotices>();
    // The front the units are routed through: `own_front`, or the caller's (GatewayOptions).
    std::unique_ptr<ModbusTcpFront> own_front;
    ModbusTcpFront* front = nullptr;
    session::UnitMap units;  // by TCP unit id, routed to once everything is open
    FrontReport closed_front;  // the figures of `own_front` when serve() closed it
    // Writes by name for the fronts below, through the lines' schedulers.
    std::unique_ptr<DeviceWriter> writer;
    // After the writer and the cache, so destroyed before them: they subscribe to the cache
    // and write through the writer.
    std::unique_ptr<MqttBridge> mqtt;
    std::unique_ptr<SparkplugNode> sparkplug;
    std::optional<SparkplugConfig> sparkplug_config;  // the [sparkplug] it runs
    KeptSparkplug* kept_sparkplug = nullptr;           // GatewayOptions::sparkplug
    std::unique_ptr<OpcuaServer> opcua;  // [opcua]; before the writer and the cache, which it uses, go
    std::unique_ptr<HttpApi> http_api;
    // `http` for the API's /metrics, which the engine's thread answers: the server serves (and may
    // be asked) before open_http has stored it in `http`. Null until then.
    std::atomic<const HttpServer*> http_serving{nullptr};
    std::unique_ptr<HttpServer> http;  // last: stopped (its connections closed) before the API goes
};

Gateway::Gateway(std::unique_ptr<Parts> parts) : parts_(std::move(parts)) {}

// A caller's front is left holding this gateway's units, never routing to lines that are gone.
Gateway::~Gateway() {
    if (parts_->front && !parts_->own_front) parts_->front->hold(parts_->units);
}

Result<std::unique_ptr<Gateway>> Gateway::open(const GatewayConfig& config, GatewayOptions options) {
    auto parts = std::make_unique<Parts>(config.modbus_tcp.enabled ? options.front : nullptr, options.lines);
    parts->statistics_interval = config.log.statistics;
    parts->alive = options.alive;
    parts->alive_every = options.alive_every;
    parts->log = options.log;
    parts->audit = std::make_shared<WriteAudit>(options.log);
    parts->wait_for_stop = options.wait_for_stop;
    parts->http_listener_kept = options.http_listener_kept;
    parts->http_logins = options.http_logins;
    session::UnitMap& units = parts->units;
    auto clock = steady_clock();
    for (const auto& line : config.lines) {
        auto kept = options.lines ? options.lines->take(line) : std::nullopt;
        auto opened = kept ? Result<OpenLine>(std::move(*kept)) : open_line(line, options, parts->simulations, parts->line_loop);
        if (!opened) return opened.error();
        bool first = true;
        for (const auto& device : line.devices) {
            ForwardingSettings settings;
            settings.line_unit = device.address.unit;
            settings.writes_allowed = config.modbus_tcp.writes;
            settings.carries_broadcasts = std::exchange(first, false);
            settings.max_age = config.modbus_tcp.max_age;
            // The writer's policy (device_writer.hpp): a write to a silent device is answered at
            // once (0Bh; 0Ah when its line is down), not forwarded to wait out the line.
            settings.write_refusal = [lookup = parts->cache.device_lookup(), name = device.name] {
                return silent_device_refusal(name, lookup(name));
            };
            settings.on_write_answered = [notices = std::weak_ptr<FrontWriteNotices>(parts->front_writes), name = device.name] {
                if (auto open = notices.lock()) open->written(name);
            };
            settings.audit = parts->audit;
            settings.device = device.name;
            units[device.tcp_unit] = std::make_shared<ForwardingUnit>(opened->scheduler, settings, clock, options.log);
        }
        parts->lines.push_back(std::move(*opened));
    }
    if (options.lines) {
        options.lines->close_untaken();
        options.lines->simulations() = parts->simulations;
    }
    std::map<std::string, std::shared_ptr<LineScheduler>> schedulers;
    for (const auto& line : parts->lines) schedulers[line.config.name] = line.scheduler;
    if (config.history) {
        auto history = open_history(*config.history, config, options.log);
        if (!history) return history.error();
        parts->history = std::move(*history);
        parts->history->audit = parts->audit;
        parts->audit->attach(parts->history->store.get());
        parts->history_subscription =
            parts->cache.subscribe([store = parts->history->store.get()](const ValueChange& change) { store->record(change); });
    }
    if (auto opened = open_alarms(config, *parts, options.log); !opened) return opened.error();
    parts->polls = std::make_unique<PollGroups>(*parts->engine, config, schedulers, parts->cache, options.log, options.samples);
    parts->front_writes->open(*parts->engine, *parts->polls);
    if (config.modbus_tcp.enabled && options.front) {
        parts->front = options.front;
    } else if (config.modbus_tcp.enabled) {
        auto front = ModbusTcpFront::open(config.modbus_tcp, {options.trace, options.debug_log});
        if (!front) return front.error();
        parts->own_front = std::move(*front);
        parts->front = parts->own_front.get();
    }
    std::vector<WritableDevice> writable;
    for (std::size_t i = 0; i < config.lines.size(); ++i) {
        for (const auto& device : config.lines[i].devices) {
            writable.push_back({device.name, device.address, parts->lines[i].scheduler});
        }
    }
    parts->writer = std::make_unique<DeviceWriter>(*parts->engine, std::move(writable), write_limit);
    // One write policy for every front: a device the polls find silent is refused at once.
    parts->writer->refuse_silent(parts->cache.device_lookup());
    parts->writer->audit(parts->audit.get(), known_values(parts->cache));
    // A write of a word that bounds a polled value shows in every front's limits at the next poll.
    parts->writer->on_written([polls = parts->polls.get()](const std::string& device, const WrittenValues& written) {
        std::vector<std::string> parameters;
        for (const auto& [name, text] : written.values) parameters.push_back(name);
        polls->written(device, parameters);
    });
    if (config.mqtt) {
        // Started here, not in serve(): it needs nothing from the TCP front, and a broker that
        // cannot be reached is retried in the background, never an error.
        // On the engine's loop: no thread of its own.
        // What each device publishes, so that what it no longer does is cleared from the broker.
        PublishedParameters published;
        for (const auto& line : config.lines) {
            for (const auto& device : line.devices) {
                auto& names = published[device.name];
                for (const device::Parameter* parameter : polled_parameters(device)) names.insert(parameter->name);
            }
        }
        parts->mqtt = std::make_unique<MqttBridge>(*config.mqtt, *parts->writer, parts->cache, options.log, MqttTiming{},
                                                   &parts->engine->loop(), std::move(published));
    }
    if (config.sparkplug) open_sparkplug(*config.sparkplug, config, *parts, options.log, options.sparkplug);
    if (config.opcua) {
        std::vector<OpcuaDevice> devices;
        for (const auto& line : config.lines) {
            for (const auto& device : line.devices) devices.push_back({device.name, line.name, polled_parameters(device)});
        }
        auto opcua = OpcuaServer::open(*config.opcua, config.name, std::move(devices), *parts->writer, parts->cache, options.log);
        if (!opcua) return opcua.error();
        parts->opcua = std::move(*opcua);
    }
    if (config.http) {
        if (auto opened = open_http(*config.http, config, options.http_listener, *parts); !opened) return opened.error();
    }
    if (parts->front) parts->front->route_to(parts->units);
    return std::unique_ptr<Gateway>(new Gateway(std::move(parts)));
}

void Gateway::open_sparkplug(const SparkplugConfig& sparkplug, const GatewayConfig& config, Parts& parts, GatewayLog log,
                             KeptSparkplug* kept) {
    parts.sparkplug_config = sparkplug;
    parts.kept_sparkplug = kept;
    std::vector<SparkplugDevice> devices;
    for (const auto& line : config.lines) {
        for (const auto& device : line.devices) devices.push_back({device.name, polled_parameters(device)});
    }
    auto lines = [&parts] {
        std::vector<SparkplugLineFigures> figures;
        for (const auto& line : parts.lines) {
            const LineReport report = report_of(line);
            figures.push_back({report.name, report.statistics.sent, report.statistics.answered, report.statistics.timeouts,
                               report.link_health.up});
        }
        return figures;
    };
    // Store and forward keeps its queue in the history file too, when there is one.
    SparkplugPending pending;
    if (sparkplug.store_and_forward && parts.history) pending = sparkplug_pending_in(*parts.history->store);
    if (kept && kept->node && kept->config == sparkplug) {
        // The last gateway's session carries on (hand_over_to).
        parts.sparkplug = std::move(kept->node);
        parts.sparkplug->take_over(std::move(devices), *parts.writer, parts.cache, std::move(lines), std::move(log),
                                   &parts.engine->loop(), std::move(pending));
        return;
    }
    if (pending.add) {
        if (auto loaded = load_sparkplug_pending(parts.history->store->database())) {
            pending.loaded = std::move(*loaded);
        } else if (log) {
            log(std::string(gateway_warning_prefix) + "sparkplug: what the last run kept to forward cannot be read (" +
                loaded.error().message + "); it is not forwarded");
        }
    }
    if (kept) kept->node.reset();  // a session for another [sparkplug]: it ends (NDEATH)
    // Like MQTT: started here, retried in the background, never an error.
    // On the engine's loop, as the MQTT front: no thread of its own.
    parts.sparkplug =
        std::make_unique<SparkplugNode>(sparkplug, std::move(devices), *parts.writer, parts.cache, std::move(lines),
                                        std::move(log), SparkplugTiming{}, &parts.engine->loop(), std::move(pending));
}

// Every device's communication alarms and the configured limit alarms, their journal in the
// history file when there is one.
Result<void> Gateway::open_alarms(const GatewayConfig& config, Parts& parts, GatewayLog log) {
    std::vector<std::string> devices;
    for (const auto& line : config.lines) {
        for (const auto& device : line.devices) devices.push_back(device.name);
    }
    alarms::AlarmJournal* journal = parts.history ? parts.history->alarm_journal.get() : nullptr;
    std::filesystem::path database = config.history ? config.history->database : std::filesystem::path();
    parts.alarms = std::make_unique<alarms::AlarmService>(*parts.engine, parts.cache, config.alarm_limits, devices, journal,
                                                          std::move(database), std::move(log));
    return {};
}

Result<void> Gateway::open_http(const HttpConfig& http, const GatewayConfig& config, HttpListener* listener,
                               Parts& parts) {
    HttpApiSources sources;
    sources.cache = &parts.cache;
    sources.writer = parts.writer.get();
    sources.history = parts.history ? parts.history->reader.get() : nullptr;
    sources.alarms = parts.alarms.get();
    sources.lines = [&parts] {
        std::vector<LineReport> reports;
        for (const auto& line : parts.lines) reports.push_back(report_of(line));
        return reports;
    };
    sources.front = [&parts] { return parts.front ? parts.front->statistics() : FrontReport{}; };
    if (parts.opcua) sources.opcua = [&parts] { return parts.opcua->figures(); };
    sources.http_not_allowed = [&parts] {
        const HttpServer* serving = parts.http_serving.load();
        return serving ? serving->not_allowed() : std::uint64_t{0};
    };
    sources.log = parts.log;
    sources.logins = parts.http_logins;
    parts.http_api = std::make_unique<HttpApi>(config, std::move(sources));
    HttpServerSettings settings;
    settings.host = http.host;
    settings.port = http.port;
    settings.read_timeout = http.read_timeout;
    settings.max_connections = http.max_connections;
    settings.max_connections_per_client = http.max_connections_per_client;
    settings.header_timeout = http.header_timeout;
    settings.max_event_streams = http.max_event_streams;
    settings.max_event_streams_per_client = http.max_event_streams_per_client;
    settings.send_timeout = http.send_timeout;
    settings.allow = http.allow;
    settings.certificate = http.certificate;
    settings.private_key = http.private_key;
    // On the engine's loop: no thread of its own (the thread count does not grow with
    // the fronts); what would block there is deferred (http_server.hpp).
    const bool kept = listener && listener->listens_as(http.host, http.port);
    auto server = HttpServer::open(settings, *parts.http_api, &parts.engine->loop(), kept ? listener : nullptr);
    if (!server) return server.error();
    parts.http = std::move(*server);
    parts.http_serving.store(parts.http.get());
    return {};
}

std::uint16_t Gateway::modbus_tcp_port() const { return parts_->front ? parts_->front->port() : 0; }

std::uint16_t Gateway::opcua_port() const { return parts_->opcua ? parts_->opcua->port() : 0; }

std::uint16_t Gateway::http_port() const { return parts_->http ? parts_->http->port() : 0; }

void Gateway::audit(AuditRecord record) const { parts_->audit->record(std::move(record)); }

Result<void> Gateway::reload_http_certificate() { return parts_->http ? parts_->http->reload_certificate() : Result<void>{}; }

namespace {

// How long a stopping gateway keeps serving so that the requests already taken are answered.
constexpr auto drain_limit = std::chrono::seconds(5);

// No client's request or write is queued or on the wire: the gateway's own polls do not count,
// since nobody waits for their answer (a poll waiting for a silent device held every stop for
// the whole drain limit).
bool lines_idle(const std::vector<OpenLine>& lines) {
    return std::all_of(lines.begin(), lines.end(), [](const OpenLine& line) { return line.scheduler->statistics().asked == 0; });
}

// Waits for `stop`, then until no line has a request of a client or a write to answer (or the
// drain limit passes): a request a client sent before SIGTERM still gets its answer before the
// front closes.
void wait_then_drain(const std::vector<OpenLine>& lines, const std::stop_token& stop,
                     const std::function<void(const std::stop_token&)>& wait_for_stop) {
    std::mutex mutex;
    std::condition_variable_any woken;
    std::unique_lock lock(mutex);
    if (wait_for_stop) {
        wait_for_stop(stop);
    } else {
        woken.wait(lock, stop, [] { return false; });
    }
    const auto give_up = std::chrono::steady_clock::now() + drain_limit;
    while (!lines_idle(lines) && std::chrono::steady_clock::now() < give_up) {
        woken.wait_for(lock, std::chrono::milliseconds(10), [] { return false; });
    }
}

LineReport report_of(const OpenLine& line) {
    return {line.config.name, line.link, line.scheduler->statistics(), line.garbled->load(std::memory_order_relaxed),
            line.master->health()};
}

// Every `interval`, on the engine's loop, each line's figures, its busy share over the interval.
class StatisticsLog {
public:
    StatisticsLog(Engine& engine, const std::vector<OpenLine>& lines, std::chrono::milliseconds interval, GatewayLog log)
        : engine_(engine), timer_(engine.loop()), lines_(lines), interval_(interval), log_(std::move(log)) {
        for (const auto& line : lines_) previous_.push_back(report_of(line));
        boost::asio::post(engine_.loop(), [this] { arm(); });
    }
    ~StatisticsLog() {
        engine_.take_down([this] {
            stopped_ = true;
            alive_.reset();
            timer_.cancel();
        });
    }
    StatisticsLog(const StatisticsLog&) = delete;
    StatisticsLog& operator=(const StatisticsLog&) = delete;

private:
    void arm() {
        if (stopped_) return;
        timer_.expires_after(interval_);
        // A wait that had expired before the take-down still runs, with no error: `alive` says
        // whether this log is still there.
        timer_.async_wait([this, alive = std::weak_ptr<const bool>(alive_)](const boost::system::error_code& error) {
            if (error || alive.expired()) return;  // cancelled or taken down: serve() is over
            for (std::size_t i = 0; i < lines_.size(); ++i) {
                LineReport now = report_of(lines_[i]);
                log_(describe(now, &previous_[i]));
                previous_[i] = std::move(now);
            }
            arm();
        });
    }

    Engine& engine_;
    boost::asio::steady_timer timer_;
    const std::vector<OpenLine>& lines_;
    std::chrono::milliseconds interval_;
    GatewayLog log_;
    std::vector<LineReport> previous_;
    bool stopped_ = false;  // on the loop's thread only
    std::shared_ptr<const bool> alive_ = std::make_shared<const bool>(true);  // reset at the take-down
};

// Calls `alive` every `every` on the engine's loop, the first time at once, until destroyed:
// the beat comes from the loop that serves the fronts and polls, not from a thread of its own.
class LoopHeartbeat {
public:
    LoopHeartbeat(Engine& engine, std::chrono::milliseconds every, std::function<void()> alive)
        : engine_(engine), timer_(engine), every_(every), alive_(std::move(alive)) {
        engine_.post([this] { beat(); });
    }
    // The take-down runs after the first beat (posted before it) and cancels the next.
    ~LoopHeartbeat() {
        engine_.take_down([this] {
            stopped_ = true;
            timer_.cancel();
        });
    }
    LoopHeartbeat(const LoopHeartbeat&) = delete;
    LoopHeartbeat& operator=(const LoopHeartbeat&) = delete;

private:
    void beat() {
        if (stopped_) return;
        alive_();
        timer_.set(engine_.clock()->now() + every_, [this] { beat(); });
    }

    Engine& engine_;
    LoopTimer timer_;  // on the loop's thread only
    std::chrono::milliseconds every_;
    std::function<void()> alive_;
    bool stopped_ = false;  // on the loop's thread only
};

}  // namespace

Result<void> Gateway::serve(std::stop_token stop) {
    std::optional<StatisticsLog> statistics;
    if (parts_->log && parts_->statistics_interval.count() > 0) {
        statistics.emplace(*parts_->engine, parts_->lines, parts_->statistics_interval, parts_->log);
    }
    std::optional<LoopHeartbeat> heartbeat;
    if (parts_->alive && parts_->alive_every.count() > 0) heartbeat.emplace(*parts_->engine, parts_->alive_every, parts_->alive);
    // Ended by `stop`, or by the front when it fails.
    std::stop_source either;
    auto end = [&either] { either.request_stop(); };
    std::stop_callback on_stop(stop, end);
    std::optional<std::stop_callback<decltype(end)>> on_front_failure;
    if (parts_->front) on_front_failure.emplace(parts_->front->failed(), end);
    wait_then_drain(parts_->lines, either.get_token(), parts_->wait_for_stop);
    Result<void> served;
    if (parts_->front && parts_->front->failed().stop_requested()) served = parts_->front->error();
    if (parts_->own_front) {
        parts_->closed_front = parts_->own_front->statistics();
        parts_->front = nullptr;
        parts_->own_front.reset();  // closes the connections
    } else if (parts_->front) {
        parts_->front->hold(parts_->units);
    }
    // The HTTP front closes with the Modbus TCP one, after the drain: writes under way answer.
    if (parts_->http) parts_->http->stop(parts_->http_listener_kept && parts_->http_listener_kept());
    return served;
}

void Gateway::hand_over_to(const GatewayConfig& next) {
    if (parts_->keeper) keep_lines_for(next);
    // The Sparkplug session goes on when the next [sparkplug] is this one: the node is left to
    // the next gateway, which tells the host only what the devices' changes call for.
    if (parts_->sparkplug && parts_->kept_sparkplug && next.sparkplug && next.sparkplug == parts_->sparkplug_config &&
        parts_->sparkplug->release()) {
        parts_->kept_sparkplug->config = *next.sparkplug;
        parts_->kept_sparkplug->node = std::move(parts_->sparkplug);
    }
    if (!parts_->mqtt) return;
    std::set<std::string> next_devices;
    for (const auto& line : next.lines) {
        for (const auto& device : line.devices) next_devices.insert(device.name);
    }
    parts_->mqtt->hand_over(next.mqtt, next_devices);
}

// The lines `next` runs as they run now stay open (line_keeper.hpp); the simulated ones only
// when all of them do, since they share one simulation.
void Gateway::keep_lines_for(const GatewayConfig& next) {
    std::vector<LineConfig> running;
    for (const auto& line : parts_->lines) running.push_back(line.config);
    const bool simulations = simulations_kept_as(running, next.lines);
    if (!simulations) parts_->keeper->simulations().reset();
    parts_->handed_over.assign(parts_->lines.size(), false);
    for (std::size_t i = 0; i < parts_->lines.size(); ++i) {
        const LineConfig& line = parts_->lines[i].config;
        if (line.simulation && !simulations) continue;
        const bool kept = std::any_of(next.lines.begin(), next.lines.end(), [&](const LineConfig& to) { return line_kept_as(line, to); });
        if (!kept) continue;
        parts_->handed_over[i] = true;
        if (parts_->log) parts_->log(fmt::format("line {} ({}) stays open across the reload", line.name, parts_->lines[i].link));
    }
}

std::vector<LineReport> Gateway::report() const {
    std::vector<LineReport> reports;
    for (const auto& line : parts_->lines) reports.push_back(report_of(line));
    return reports;
}

FrontReport Gateway::front_report() const { return parts_->front ? parts_->front->statistics() : parts_->closed_front; }

std::vector<CachedDevice> Gateway::values() const { return parts_->cache.snapshot(); }

ValueSubscription Gateway::subscribe(ValueCallback callback) { return parts_->cache.subscribe(std::move(callback)); }

Result<void> check_history_forwarding(const GatewayConfig& config) {
    if (!config.history) return {};
    const auto forward = forward_options(*config.history, config);
    if (!forward) return {};
    auto checked = check_forward_target(*forward);
    if (!checked) {
        return make_error(checked.error().kind,
                          fmt::format("{}: history.forward_to: {}", config.history->written_at, checked.error().message));
    }
    return {};
}

const HistorySource* Gateway::history() const { return parts_->history ? parts_->history->reader.get() : nullptr; }

std::string describe(const LineReport& report, const LineReport* since) {
    const auto& s = report.statistics;
    const auto busy_time = s.busy - (since ? since->statistics.busy : std::chrono::microseconds(0));
    const auto open_time = s.open - (since ? since->statistics.open : std::chrono::microseconds(0));
    const double busy = open_time.count() > 0 ? 100.0 * static_cast<double>(busy_time.count()) / static_cast<double>(open_time.count()) : 0.0;
    const std::string period = since ? fmt::format("over the last {:.0f} s", static_cast<double>(open_time.count()) / 1e6) : "of the time";
    const auto& health = report.link_health;
    const std::string down_now = health.up ? "" : fmt::format(" is DOWN ({}; retrying in {} s)", health.reason,
                                                               std::chrono::ceil<std::chrono::seconds>(health.retry_in).count());
    return fmt::format("line {} ({}){}: {} sent, {} answered, {} timeout(s), {} bad repl{}, {} garbled frame(s), {} expired in "
                       "the queue, {} dropped as their client had gone, {} polls held back while the unit backed off, {} "
                       "refused with the queue full, down {} time(s) ({} reopen attempt(s), {} request(s) refused while "
                       "down); busy {:.1f} % {}; {} of the requests sent were polls",
                       report.name, report.link, down_now, s.sent, s.answered, s.timeouts, s.bad_replies,
                       s.bad_replies == 1 ? "y" : "ies", report.garbled, s.expired, s.abandoned, s.backed_off,
                       s.refused_busy, health.down_periods, health.reopen_attempts, health.refused_while_down, busy,
                       period, s.polls_sent);
}

std::string describe(const FrontReport& report) {
    return fmt::format("Modbus TCP front: {} connection(s) accepted, {} closed to admit a newer one, {} refused with every "
                       "connection busy, {} closed idle, {} refused by the allow list; {} open",
                       report.accepted, report.evicted, report.refused, report.idle_closed, report.not_allowed, report.open);
}

}  // namespace loopwire::gateway
