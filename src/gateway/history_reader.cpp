#include "gateway/history_reader.hpp"

#include <future>

#include <fmt/format.h>

#include "common/thread_name.hpp"
#include "gateway/history_forwarder.hpp"
#include "gateway/history_query.hpp"
#include "gateway/history_schema.hpp"
#include "gateway/history_store.hpp"

namespace loopwire::gateway {

HistoryReader::HistoryReader(HistoryReaderOptions options, const HistoryStore& store, const HistoryForwarder* forwarder)
    : options_(std::move(options)), store_(store), forwarder_(forwarder) {}

Result<std::unique_ptr<HistoryReader>> HistoryReader::open(HistoryReaderOptions options, const HistoryStore& store,
                                                           const HistoryForwarder* forwarder) {
    // Read-only: the writer's connection, open already, keeps the file's WAL and its index.
    auto db = history::open_for_reading(options.database, sqlite::Connection::Mode::read_only);
    if (!db) return db.error();
    std::unique_ptr<HistoryReader> reader(new HistoryReader(std::move(options), store, forwarder));
    reader->db_ = std::move(*db);
    if (const auto& historian = reader->options_.historian) {
        reader->historian_ = std::make_unique<HistorianReader>(historian->conninfo, historian->password, historian->limits);
    }
    if (reader->options_.thread) {
        reader->threaded_ = true;
        reader->thread_ = std::jthread([r = reader.get()](std::stop_token stop) { r->run(std::move(stop)); });
        name_thread(reader->thread_.native_handle(), "lw-history-rd");
    }
    return reader;
}

HistoryReader::~HistoryReader() {
    thread_ = std::jthread();  // stops and joins: the asks left run there, as asked
}

void HistoryReader::run(std::stop_token stop) {
    for (;;) {
        std::function<void()> ask;
        {
            std::unique_lock lock(asks_mutex_);
            asks_woken_.wait(lock, stop, [this] { return !asks_.empty(); });
            if (asks_.empty()) {
                // Stopping with nothing queued: what is given from now on runs where it is given.
                threaded_ = false;
                return;
            }
            ask = std::move(asks_.front());
            asks_.pop_front();
        }
        ask();  // an asker waits for each, so those queued at the stop still run
    }
}

void HistoryReader::run_blocking(std::function<void()> work) const {
    {
        std::lock_guard lock(asks_mutex_);
        if (threaded_) {
            asks_.push_back(std::move(work));
            asks_woken_.notify_one();
            return;
        }
    }
    work();
}

// The connections are the reader thread's alone: an ask from elsewhere is queued for it.
template <typename T>
Result<T> HistoryReader::on_reader_thread(std::function<Result<T>()> ask) const {
    if (std::this_thread::get_id() == thread_.get_id()) return ask();
    std::promise<Result<T>> answer;
    auto answered = answer.get_future();
    run_blocking([&answer, &ask] { answer.set_value(ask()); });
    return answered.get();
}

Result<std::vector<HistorySeries>> HistoryReader::query(const HistoryQuery& query) const {
    const bool own = query.gateway.empty() || query.gateway == options_.gateway;
    return on_reader_thread<std::vector<HistorySeries>>([&] { return own ? read_file(query) : read_historian(query); });
}

Result<std::vector<std::string>> HistoryReader::historian_gateways() const {
    if (!historian_) return HistorySource::historian_gateways();
    return on_reader_thread<std::vector<std::string>>([this] { return historian_->gateways(); });
}

Result<std::vector<AuditRecord>> HistoryReader::audit(const AuditQuery& query) const {
    return on_reader_thread<std::vector<AuditRecord>>([&] { return history::run_audit_query(db_, query); });
}

std::uint64_t HistoryReader::rows_written() const { return store_.rows_written(); }

std::optional<ForwardStats> HistoryReader::forward_stats() const {
    if (!forwarder_) return std::nullopt;
    return forwarder_->stats();
}

Result<std::vector<HistorySeries>> HistoryReader::read_file(const HistoryQuery& query) const {
    return history::run_query(db_, with_look_back(query));
}

// Another gateway's history: in the shared historian this gateway forwards to.
Result<std::vector<HistorySeries>> HistoryReader::read_historian(const HistoryQuery& query) const {
    if (!historian_) {
        return make_error(ErrorKind::usage, fmt::format("gateway=\"{}\": only this gateway's history is kept here; another's "
                                                        "needs [history] forward_to, the historian they share", query.gateway));
    }
    return historian_->query(query.gateway, with_look_back(query));
}

// Twice the heartbeat: a value still read is written again at least every heartbeat (and the
// writer's commit interval), so a value in force at `from` has a row within one heartbeat
// before it; the second one allows for a late commit (a retried write). An older last row
// means the gateway recorded nothing since (it was stopped): no value is known at `from`.
// Another gateway's history is asked with the same bound: gateways sharing a historian are
// expected to share a heartbeat; one with a longer one only loses its starting value.
HistoryQuery HistoryReader::with_look_back(HistoryQuery query) const {
    query.look_back = 2 * options_.heartbeat;
    return query;
}

}  // namespace loopwire::gateway
