#include "gateway/device_writer.hpp"

#include <algorithm>
#include <condition_variable>
#include <cstdlib>
#include <deque>
#include <future>
#include <mutex>
#include <utility>

#include <fmt/format.h>

#include "gateway/scheduled_master.hpp"
#include "profile/request_planner.hpp"

namespace loopwire::gateway {

std::optional<Error> silent_device_refusal(const std::string& device, const std::optional<DeviceSeen>& seen) {
    if (!seen) return std::nullopt;
    const auto why = [&](const char* otherwise) { return seen->error.empty() ? std::string(otherwise) : seen->error; };
    switch (seen->status) {
        case device::DeviceStatus::no_reply:
            return make_error(ErrorKind::timeout,
                              fmt::format("device \"{}\" does not answer its polls ({}); nothing was sent: write again once "
                                          "its status is \"ok\"", device, why("its polls time out")));
        case device::DeviceStatus::line_down:
            return make_error(ErrorKind::link,
                              fmt::format("device \"{}\" cannot be reached: its line is down ({}); nothing was sent: write "
                                          "again once its status is \"ok\"", device, why("the line failed")));
        case device::DeviceStatus::wrong_device:
            return make_error(ErrorKind::mismatch,
                              fmt::format("device \"{}\": what answers at its address is not the configured device ({}); "
                                          "nothing was sent", device, why("its identification differs")));
        case device::DeviceStatus::waiting:
        case device::DeviceStatus::ok:
        case device::DeviceStatus::partial:
        case device::DeviceStatus::stale: return std::nullopt;
    }
    return std::nullopt;  // not reached: every status is handled above
}

namespace {

// The audit records of one write, one an assignment, finished once with the write's outcome.
struct AuditedWrite {
    const WriteAudit* audit = nullptr;
    std::vector<AuditRecord> records;

    void finish(const std::string& outcome) {
        for (auto& record : records) {
            record.outcome = outcome;
            audit->record(std::move(record));
        }
        records.clear();
    }
};

// "160" as the cache shows the parameter's values ("160.0 °C"); a text that is no number (an
// enum label) as it was given.
std::string in_units(const std::string& text, const std::optional<KnownValue>& known, const std::string& profile_unit) {
    const std::string unit = known && !known->unit.empty() ? known->unit : profile_unit;
    std::string shown = text;
    if (known) {
        char* end = nullptr;
        const double number = std::strtod(text.c_str(), &end);
        if (end && *end == '\0' && end != text.c_str()) shown = fmt::format("{:.{}f}", number, std::max(known->decimals, 0));
    }
    return unit.empty() ? shown : fmt::format("{} {}", shown, unit);
}

// The record of an assignment once its parameter is known: the profile's name, the value the
// polls last read and the one written, in engineering units.
void name_in_record(AuditRecord& record, const device::Parameter& parameter, const std::string& text,
                    const KnownValueLookup& known_values) {
    const auto known = known_values ? known_values(record.device, parameter.name) : std::nullopt;
    record.parameter = parameter.name;
    if (known) record.old_value = known->unit.empty() ? known->text : fmt::format("{} {}", known->text, known->unit);
    if (!text.empty()) record.new_value = in_units(text, known, parameter.unit);
}

// One record an assignment (one for the whole write when it has none), each as given until
// its parameter is known.
std::vector<AuditRecord> records_of(const WriteOrigin& origin, const std::string& device,
                                    const std::vector<WriteAssignment>& assignments) {
    std::vector<AuditRecord> records;
    for (const auto& assignment : assignments) {
        AuditRecord record;
        record.origin = origin;
        record.device = device;
        record.parameter = assignment.parameter;
        record.new_value = assignment.text;
        records.push_back(std::move(record));
    }
    if (records.empty()) {
        AuditRecord record;
        record.origin = origin;
        record.device = device;
        records.push_back(std::move(record));
    }
    return records;
}

}  // namespace

struct DeviceWriter::Target {
    WritableDevice device;
    LineWriter* line = nullptr;
};

// One line's writes, one after the other, driven from the engine's loop: each starts there and
// its requests go to the line's scheduler without blocking, so a dead line holds up only the
// writes that wait for it, and no thread waits for any line.
struct DeviceWriter::LineWriter {
    struct Job {
        const Target* target = nullptr;
        std::vector<std::pair<const device::Parameter*, std::string>> planned;
        WrittenValues written;
        Instant given_up;  // not started after this: the front's asker has waited enough
        WriteCompletion done;
    };

    // The write under way: the client and master it goes through live until its end.
    struct Running {
        Running(std::shared_ptr<LineScheduler> line, const WritableDevice& device, std::chrono::milliseconds left,
                std::shared_ptr<Clock> clock)
            : name(device.name), master(std::move(line), "write " + device.name, Priority::write, left, std::move(clock)),
              client(master, device.address) {}
        std::string name;  // the device's, as configured
        ScheduledMaster master;
        device::DeviceClient client;
    };

    LineWriter(EventLoop& engine_loop, std::shared_ptr<LineScheduler> scheduler, std::chrono::milliseconds given_up_after,
               std::size_t queue_limit, std::shared_ptr<const WrittenHook> hook)
        : loop(engine_loop), written_hook(std::move(hook)), line(std::move(scheduler)), write_limit(given_up_after), limit(queue_limit) {}

    EventLoop& loop;
    std::shared_ptr<const WrittenHook> written_hook;
    std::shared_ptr<LineScheduler> line;
    std::chrono::milliseconds write_limit;
    std::size_t limit;
    mutable std::mutex mutex;
    std::condition_variable idle;
    std::deque<Job> queue;
    bool busy = false;      // a job is under way, or the next is about to start
    bool stopping = false;

    bool submit(Job job) {
        bool start = false;
        {
            std::lock_guard lock(mutex);
            if (queue.size() >= limit) return false;
            queue.push_back(std::move(job));
            start = !std::exchange(busy, true);
        }
        if (start) loop.post([this] { start_next(); });
        return true;
    }

    std::size_t pending() const {
        std::lock_guard lock(mutex);
        return queue.size() + (busy ? 1 : 0);
    }

    // On the loop's thread: the next job that is still wanted, or the line goes idle.
    void start_next() {
        for (;;) {
            Job job;
            {
                std::lock_guard lock(mutex);
                if (stopping || queue.empty()) {
                    busy = false;
                    idle.notify_all();
                    return;
                }
                job = std::move(queue.front());
                queue.pop_front();
            }
            const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(job.given_up - loop.clock()->now());
            if (left <= std::chrono::milliseconds(0)) {
                job.done(make_error(ErrorKind::timeout,
                                    fmt::format("device \"{}\": its line was busy with other writes for {} ms; nothing was "
                                                "written (write again)", job.target->device.name, write_limit.count())));
                continue;
            }
            // Each request of the write may wait for the line only as long as the write has left.
            auto running = std::make_shared<Running>(line, job.target->device, left, loop.clock());
            auto& client = running->client;
            client.write_async(std::move(job.planned),
                               [this, running, written = std::move(job.written), done = std::move(job.done)](
                                   Result<device::WriteReport> report) mutable {
                                   Result<WrittenValues> outcome = report ? Result<WrittenValues>(std::move(written))
                                                                          : Result<WrittenValues>(running->client.explain(report.error()));
                                   // Here is the line's worker: everything the write holds is
                                   // moved to the loop and let go there. The write's master could
                                   // be the last hold on the line once the gateway is stopping, and
                                   // a line's master must not end inside one of its own jobs
                                   // (job_queue.hpp): it would wait for itself. The asker's
                                   // completion may hold its front's connection (the HTTP API's),
                                   // whose timers belong to the front's thread: answered and let
                                   // go on the loop, its last hold is never dropped here.
                                   loop.post([this, finished = std::move(running), done = std::move(done),
                                              outcome = std::move(outcome)]() mutable {
                                       if (outcome && *written_hook) (*written_hook)(finished->name, *outcome);
                                       done(std::move(outcome));
                                       done = nullptr;
                                       finished.reset();
                                       start_next();
                                   });
                               });
            return;
        }
    }

    // What is still queued is answered, never dropped without a word; the write under way ends
    // first (its line's timeout at most).
    void stop() {
        std::deque<Job> left;
        {
            std::unique_lock lock(mutex);
            stopping = true;
            left.swap(queue);
        }
        for (auto& job : left) {
            job.done(make_error(ErrorKind::link, fmt::format("device \"{}\": the gateway is stopping; nothing was written",
                                                             job.target->device.name)));
        }
        std::unique_lock lock(mutex);
        idle.wait(lock, [this] { return !busy; });
    }
};

DeviceWriter::DeviceWriter(EventLoop& loop, std::vector<WritableDevice> devices, std::chrono::milliseconds write_limit,
                           std::size_t queue_limit)
    : loop_(loop) {
    for (auto& device : devices) {
        LineWriter* writer = nullptr;
        for (const auto& line : lines_) {
            if (line->line == device.line) writer = line.get();
        }
        if (!writer) {
            lines_.push_back(std::make_unique<LineWriter>(loop, device.line, write_limit, queue_limit, written_hook_));
            writer = lines_.back().get();
        }
        targets_.push_back(std::make_unique<Target>(Target{std::move(device), writer}));
    }
}

DeviceWriter::~DeviceWriter() {
    // Before the targets the jobs point at are gone.
    for (auto& line : lines_) line->stop();
}

const WritableDevice* DeviceWriter::find(const std::string& name) const {
    for (const auto& target : targets_) {
        if (target->device.name == name) return &target->device;
    }
    return nullptr;
}

std::vector<std::string> DeviceWriter::device_names() const {
    std::vector<std::string> names;
    names.reserve(targets_.size());
    for (const auto& target : targets_) names.push_back(target->device.name);
    return names;
}

bool DeviceWriter::write_async(const std::string& device, std::vector<WriteAssignment> assignments, WriteCompletion done,
                               WriteOrigin origin) const {
    // Every way out below runs `done` once (or returns false, busy): the audit's records are
    // finished in the completion, so each assignment is recorded once whatever happens.
    std::shared_ptr<AuditedWrite> audited;
    if (audit_) {
        audited = std::make_shared<AuditedWrite>();
        audited->audit = audit_;
        audited->records = records_of(origin, device, assignments);
        done = [audited, done = std::move(done)](Result<WrittenValues> outcome) {
            audited->finish(outcome ? std::string(audit_confirmed) : audit_refused(outcome.error().message));
            done(std::move(outcome));
        };
    }
    const Target* target = nullptr;
    for (const auto& candidate : targets_) {
        if (candidate->device.name == device) target = candidate.get();
    }
    if (!target) {
        done(make_error(ErrorKind::usage, fmt::format("no device \"{}\" on this gateway", device)));
        return true;
    }
    if (assignments.empty()) {
        done(make_error(ErrorKind::usage, "no value given"));
        return true;
    }
    LineWriter::Job job;
    job.target = target;
    for (auto& assignment : assignments) {
        // The CLI's resolution: names, aliases (PV, SP, OUT), then the manual's mnemonics.
        auto resolved = device::resolve_parameters(*target->device.address.profile, {assignment.parameter});
        if (!resolved) {
            done(make_error(ErrorKind::usage, fmt::format("device \"{}\": {}", device, resolved.error().message)));
            return true;
        }
        if (resolved->size() != 1) {
            done(make_error(ErrorKind::usage, fmt::format("device \"{}\": \"{}\" names {} parameters; write them one by one",
                                                          device, assignment.parameter, resolved->size())));
            return true;
        }
        const device::Parameter* parameter = resolved->front();
        if (audited) name_in_record(audited->records[job.planned.size()], *parameter, assignment.text, known_);
        if (assignment.text.empty()) {
            done(make_error(ErrorKind::usage, fmt::format("no value given for {}", parameter->name)));
            return true;
        }
        job.written.values.emplace_back(parameter->name, assignment.text);
        job.planned.emplace_back(parameter, std::move(assignment.text));
    }
    // The names and values are checked first: what is wrong with the write itself is worth
    // saying whatever the device's state.
    if (auto refused = refusal(device)) {
        done(std::move(*refused));
        return true;
    }
    job.given_up = loop_.clock()->now() + target->line->write_limit;
    job.done = std::move(done);
    if (target->line->submit(std::move(job))) return true;
    if (audited) audited->finish(audit_refused(fmt::format("busy: the line of device \"{}\" has too many writes waiting", device)));
    return false;
}

Result<WrittenValues> DeviceWriter::write(const std::string& device, const std::vector<WriteAssignment>& assignments,
                                          WriteOrigin origin) const {
    std::promise<Result<WrittenValues>> answered;
    auto future = answered.get_future();
    const bool queued =
        write_async(device, assignments, [&answered](Result<WrittenValues> outcome) { answered.set_value(std::move(outcome)); },
                    std::move(origin));
    if (!queued) {
        return make_error(ErrorKind::link, fmt::format("device \"{}\": its line has too many writes waiting; write again later",
                                                       device));
    }
    return future.get();
}

void DeviceWriter::on_written(WrittenHook hook) { *written_hook_ = std::move(hook); }

void DeviceWriter::audit_refusal(const std::string& device, const std::vector<WriteAssignment>& assignments,
                                 const WriteOrigin& origin, const std::string& reason) const {
    if (!audit_) return;
    AuditedWrite audited{audit_, records_of(origin, device, assignments)};
    if (const WritableDevice* target = find(device)) {
        for (std::size_t i = 0; i < assignments.size(); ++i) {
            auto resolved = device::resolve_parameters(*target->address.profile, {assignments[i].parameter});
            if (resolved && resolved->size() == 1) name_in_record(audited.records[i], *resolved->front(), assignments[i].text, known_);
        }
    }
    audited.finish(audit_refused(reason));
}

void DeviceWriter::audit(const WriteAudit* audit, KnownValueLookup known) {
    audit_ = audit;
    known_ = std::move(known);
}

void DeviceWriter::refuse_silent(DeviceLookup lookup) { lookup_ = std::move(lookup); }

std::optional<Error> DeviceWriter::refusal(const std::string& device) const {
    if (!lookup_) return std::nullopt;
    return silent_device_refusal(device, lookup_(device));
}

std::size_t DeviceWriter::pending() const {
    std::size_t total = 0;
    for (const auto& line : lines_) total += line->pending();
    return total;
}

}  // namespace loopwire::gateway
