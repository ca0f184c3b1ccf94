#include "gateway/device_writer.hpp"

#include <condition_variable>
#include <deque>
#include <future>
#include <mutex>
#include <stop_token>
#include <thread>

#include <fmt/format.h>

#include "gateway/scheduled_master.hpp"
#include "profile/request_planner.hpp"

namespace loopwire::gateway {

using Clock = std::chrono::steady_clock;

struct DeviceWriter::Target {
    WritableDevice device;
    LineWriter* line = nullptr;
};

// One line's writes, taken one after the other on a thread of the line's own: a dead line
// holds up only the writes that wait for it.
struct DeviceWriter::LineWriter {
    struct Job {
        const Target* target = nullptr;
        std::vector<std::pair<const device::Parameter*, std::string>> planned;
        WrittenValues written;
        Clock::time_point given_up;  // not started after this: the front's asker has waited enough
        WriteCompletion done;
    };

    LineWriter(std::shared_ptr<LineScheduler> scheduler, std::chrono::milliseconds given_up_after, std::size_t queue_limit)
        : line(std::move(scheduler)), write_limit(given_up_after), limit(queue_limit) {
        thread = std::jthread([this](std::stop_token stop) { run(stop); });
    }

    std::shared_ptr<LineScheduler> line;
    std::chrono::milliseconds write_limit;
    std::size_t limit;
    mutable std::mutex mutex;
    std::condition_variable_any arrived;
    std::deque<Job> queue;
    bool busy = false;  // a job is under way
    std::jthread thread;

    bool submit(Job job) {
        {
            std::lock_guard lock(mutex);
            if (queue.size() >= limit) return false;
            queue.push_back(std::move(job));
        }
        arrived.notify_one();
        return true;
    }

    std::size_t pending() const {
        std::lock_guard lock(mutex);
        return queue.size() + (busy ? 1 : 0);
    }

    void run(const std::stop_token& stop) {
        for (;;) {
            Job job;
            {
                std::unique_lock lock(mutex);
                busy = false;
                if (!arrived.wait(lock, stop, [this] { return !queue.empty(); })) break;
                job = std::move(queue.front());
                queue.pop_front();
                busy = true;
            }
            job.done(execute(job));
        }
        // Stopping: what is still queued is answered, never dropped without a word.
        std::deque<Job> left;
        {
            std::lock_guard lock(mutex);
            left.swap(queue);
        }
        for (auto& job : left) {
            job.done(make_error(ErrorKind::link, fmt::format("device \"{}\": the gateway is stopping; nothing was written",
                                                             job.target->device.name)));
        }
    }

    Result<WrittenValues> execute(Job& job) const {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(job.given_up - Clock::now());
        const WritableDevice& device = job.target->device;
        if (left <= std::chrono::milliseconds(0)) {
            return make_error(ErrorKind::timeout,
                              fmt::format("device \"{}\": its line was busy with other writes for {} ms; nothing was "
                                          "written (write again)", device.name, write_limit.count()));
        }
        // Each request of the write may wait for the line only as long as the write has left.
        ScheduledMaster master(line, "write " + device.name, Priority::write, left);
        device::DeviceClient client(master, device.address);
        auto report = client.write(job.planned);
        if (!report) return client.explain(report.error());
        return std::move(job.written);
    }
};

DeviceWriter::DeviceWriter(std::vector<WritableDevice> devices, std::chrono::milliseconds write_limit, std::size_t queue_limit) {
    for (auto& device : devices) {
        LineWriter* writer = nullptr;
        for (const auto& line : lines_) {
            if (line->line == device.line) writer = line.get();
        }
        if (!writer) {
            lines_.push_back(std::make_unique<LineWriter>(device.line, write_limit, queue_limit));
            writer = lines_.back().get();
        }
        targets_.push_back(std::make_unique<Target>(Target{std::move(device), writer}));
    }
}

DeviceWriter::~DeviceWriter() {
    // Before the targets the jobs point at are gone.
    for (auto& line : lines_) {
        line->thread.request_stop();
        line->thread.join();
    }
}

const WritableDevice* DeviceWriter::find(const std::string& name) const {
    for (const auto& target : targets_) {
        if (target->device.name == name) return &target->device;
    }
    return nullptr;
}

bool DeviceWriter::write_async(const std::string& device, std::vector<WriteAssignment> assignments, WriteCompletion done) const {
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
        if (assignment.text.empty()) {
            done(make_error(ErrorKind::usage, fmt::format("no value given for {}", parameter->name)));
            return true;
        }
        job.written.values.emplace_back(parameter->name, assignment.text);
        job.planned.emplace_back(parameter, std::move(assignment.text));
    }
    job.given_up = Clock::now() + target->line->write_limit;
    job.done = std::move(done);
    return target->line->submit(std::move(job));
}

Result<WrittenValues> DeviceWriter::write(const std::string& device, const std::vector<WriteAssignment>& assignments) const {
    std::promise<Result<WrittenValues>> answered;
    auto future = answered.get_future();
    const bool queued =
        write_async(device, assignments, [&answered](Result<WrittenValues> outcome) { answered.set_value(std::move(outcome)); });
    if (!queued) {
        return make_error(ErrorKind::link, fmt::format("device \"{}\": its line has too many writes waiting; write again later",
                                                       device));
    }
    return future.get();
}

std::size_t DeviceWriter::pending() const {
    std::size_t total = 0;
    for (const auto& line : lines_) total += line->pending();
    return total;
}

}  // namespace loopwire::gateway
