// The history store's query goal ("one parameter over 30 days at 1 s resolution answers
// in under 200 ms"): fills a database with DAYS days of one parameter sampled every second
// (and a few others every minute) through the store's own writer, then times the 500-point
// query against the same question put to the sqlite3 shell as a plain GROUP BY over the
// samples, on the same file in the same run, and checks that both give the same buckets.
//
//   history_query [DAYS] [FOLDER]      DAYS 30 by default; FOLDER: a temporary one
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "gateway/history_reader.hpp"
#include "gateway/history_store.hpp"

namespace {

using namespace loopwire::gateway;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

const SystemTime start = SystemTime(std::chrono::seconds(1767225600));  // 2026-01-01T00:00:00Z
constexpr std::size_t points = 500;
constexpr int others = 3;

ValueChange change(const std::string& parameter, double value, SystemTime sampled) {
    ValueChange c;
    c.device = "furnace";
    c.parameter = parameter;
    c.unit = "°C";
    c.status = "ok";
    c.value = loopwire::device::EngineeringValue{value, "ok", 0, ""};
    c.sampled = sampled;
    return c;
}

// The CPU time this thread used: what a query costs whatever else the machine runs.
double thread_cpu_ms() {
    timespec now{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
    return static_cast<double>(now.tv_sec) * 1e3 + static_cast<double>(now.tv_nsec) / 1e6;
}

double elapsed_ms(Clock::time_point since) { return std::chrono::duration<double, std::milli>(Clock::now() - since).count(); }

double median(std::vector<double> values) {
    std::sort(values.begin(), values.end());
    return values[values.size() / 2];
}

struct NaiveBucket {
    double min = 0, max = 0, mean = 0;
    std::size_t count = 0;
};

// The sqlite3 shell's answer and its own timing of the query ("Run Time: real S"), which
// leaves out the shell's start.
bool run_naive(const std::filesystem::path& file, const std::filesystem::path& folder, const std::string& sql,
               std::map<std::int64_t, NaiveBucket>& buckets, double& ms, double& cpu_ms) {
    const auto script = folder / "naive.sql";
    const auto output = folder / "naive.out";
    std::ofstream(script) << ".timer on\n.mode list\n" << sql << "\n";
    const std::string command = fmt::format("sqlite3 -readonly '{}' < '{}' > '{}' 2>&1", file.string(), script.string(), output.string());
    if (std::system(command.c_str()) != 0) {
        std::fprintf(stderr, "history_query: `%s` failed (is the sqlite3 shell installed? scripts/setup installs it)\n", command.c_str());
        return false;
    }
    std::ifstream in(output);
    std::string line;
    buckets.clear();
    ms = -1;
    while (std::getline(in, line)) {
        double real = 0, user = 0, sys = 0;
        if (std::sscanf(line.c_str(), "Run Time: real %lf user %lf sys %lf", &real, &user, &sys) == 3) {
            ms = real * 1000;
            cpu_ms = (user + sys) * 1000;
            continue;
        }
        long long index = 0;
        NaiveBucket b;
        if (std::sscanf(line.c_str(), "%lld|%lf|%lf|%lf|%zu", &index, &b.min, &b.max, &b.mean, &b.count) == 5) buckets[index] = b;
    }
    if (ms < 0) {
        std::fprintf(stderr, "history_query: the sqlite3 shell printed no timing\n");
        return false;
    }
    return true;
}

}  // namespace

int main(int argc, char** argv) {
    const int days = argc > 1 ? std::atoi(argv[1]) : 30;
    if (days < 1 || days > 365) {
        std::fprintf(stderr, "usage: history_query [DAYS 1..365] [FOLDER]\n");
        return 2;
    }
    std::filesystem::path folder;
    bool temporary = argc <= 2;
    if (temporary) {
        std::string pattern = (std::filesystem::temp_directory_path() / "loopwire-history-bench-XXXXXX").string();
        if (!mkdtemp(pattern.data())) return 1;
        folder = pattern;
    } else {
        folder = argv[2];
    }
    const auto file = folder / "bench.db";
    std::filesystem::remove(file);

    HistoryOptions options;
    options.database = file;
    // No writer thread (not started): the bench commits itself, a day at a time.
    options.keep = std::chrono::hours(24 * 3650);
    options.wall_clock = [] { return start; };  // no heartbeats, no retention while filling
    auto store = HistoryStore::open(options);
    if (!store) {
        std::fprintf(stderr, "history_query: %s\n", store.error().message.c_str());
        return 1;
    }
    // A slow wave with noise and a spike a day: what a furnace's measured value looks like.
    const std::int64_t seconds = static_cast<std::int64_t>(days) * 86400;
    std::uint64_t noise = 12345;
    const auto fill_started = Clock::now();
    for (std::int64_t s = 0; s < seconds; ++s) {
        noise = noise * 6364136223846793005ULL + 1442695040888963407ULL;
        double value = 850 + 30 * std::sin(static_cast<double>(s) / 3600.0) + static_cast<double>(noise >> 54) / 512.0;
        if (s % 86400 == 43200) value += 200;
        const SystemTime at = start + std::chrono::seconds(s);
        (*store)->record(change("measured_value", value, at));
        if (s % 60 == 0) {
            for (int k = 0; k < others; ++k) (*store)->record(change(fmt::format("zone{}", k), value - 10.0 * k, at));
        }
        if (s % 86400 == 86399) {
            if (auto written = (*store)->write_pending(); !written) {
                std::fprintf(stderr, "history_query: %s\n", written.error().message.c_str());
                return 1;
            }
        }
    }
    if (auto written = (*store)->write_pending(); !written) return 1;
    const double fill_ms = elapsed_ms(fill_started);
    const auto rows = (*store)->rows_written();
    // The gateway's reader, without its thread: the query runs, and is timed, on this one.
    HistoryReaderOptions reading;
    reading.database = file;
    reading.heartbeat = options.heartbeat;
    reading.thread = false;
    auto reader = HistoryReader::open(reading, **store);
    if (!reader) {
        std::fprintf(stderr, "history_query: %s\n", reader.error().message.c_str());
        return 1;
    }

    HistoryQuery query;
    query.device = "furnace";
    query.parameters = {"measured_value"};
    query.from = start;
    query.to = start + std::chrono::seconds(seconds) - 1ms;
    query.points = points;
    std::vector<double> times;
    std::vector<double> cpu_times;
    std::vector<HistorySeries> answer;
    for (int i = 0; i < 15; ++i) {
        const auto began = Clock::now();
        const double cpu_began = thread_cpu_ms();
        auto series = (*reader)->query(query);
        times.push_back(elapsed_ms(began));
        cpu_times.push_back(thread_cpu_ms() - cpu_began);
        if (!series) {
            std::fprintf(stderr, "history_query: %s\n", series.error().message.c_str());
            return 1;
        }
        answer = std::move(*series);
    }
    const double ours = median(times);
    const double ours_cpu = median(cpu_times);

    // The same buckets as a plain GROUP BY over every sample in the range.
    const auto ms = [](SystemTime t) { return std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count(); };
    const BucketPlan plan = plan_buckets(ms(query.from), ms(query.to), points);
    const std::string sql = fmt::format(
        "SELECT (t - {0}) / {1}, min(value), max(value), avg(value), count(value) FROM samples "
        "WHERE series_id = (SELECT id FROM series WHERE device = 'furnace' AND parameter = 'measured_value') "
        "AND t >= {2} AND t <= {3} GROUP BY 1;",
        plan.origin, plan.width, ms(query.from), ms(query.to));
    std::vector<double> naive_times;
    std::vector<double> naive_cpu_times;
    std::map<std::int64_t, NaiveBucket> naive;
    for (int i = 0; i < 3; ++i) {
        double naive_ms = 0, naive_cpu_ms = 0;
        if (!run_naive(file, folder, sql, naive, naive_ms, naive_cpu_ms)) return 1;
        naive_times.push_back(naive_ms);
        naive_cpu_times.push_back(naive_cpu_ms);
    }
    const double peer = median(naive_times);
    const double peer_cpu = median(naive_cpu_times);

    const auto& buckets = answer.at(0).buckets;
    bool agree = buckets.size() == naive.size() && !buckets.empty();
    for (const auto& bucket : buckets) {
        const auto index = (ms(bucket.start) - plan.origin) / plan.width;
        const auto found = naive.find(index);
        // The shell prints 15 significant digits: equal to that.
        const auto near = [](double a, double b) { return std::abs(a - b) <= 1e-12 * std::max(std::abs(a), std::abs(b)); };
        if (found == naive.end() || found->second.count != bucket.count || !near(found->second.min, bucket.min) ||
            !near(found->second.max, bucket.max) || !near(found->second.mean, bucket.mean)) {
            if (agree && found != naive.end()) {
                std::fprintf(stderr, "history_query: bucket %lld: loopwire min %.17g max %.17g mean %.17g count %zu; GROUP BY min %.17g "
                             "max %.17g mean %.17g count %zu\n", static_cast<long long>(index), bucket.min, bucket.max, bucket.mean,
                             bucket.count, found->second.min, found->second.max, found->second.mean, found->second.count);
            }
            agree = false;
        }
    }
    if (!agree) {
        std::fprintf(stderr, "history_query: the store's %zu buckets differ from the plain GROUP BY's %zu\n", buckets.size(), naive.size());
        return 1;
    }
    reader->reset();
    store->reset();  // closing checkpoints the WAL into the file
    std::error_code error;
    const auto size = std::filesystem::file_size(file, error);
    std::printf("history: %llu rows written (%d day(s) of one parameter at 1 s, %d more each minute) in %.1f s: %.0f rows/s; "
                "file %.1f MB\n",
                static_cast<unsigned long long>(rows), days, others, fill_ms / 1000, static_cast<double>(rows) / (fill_ms / 1000),
                error ? 0.0 : static_cast<double>(size) / 1e6);
    std::printf("history query of %d day(s) at 1 s into %zu points: loopwire %.2f ms (CPU %.2f ms; median of %zu), sqlite3 "
                "shell GROUP BY %.2f ms (CPU %.2f ms; median of %zu), naive/loopwire: %.1f; buckets agree\n",
                days, buckets.size(), ours, ours_cpu, times.size(), peer, peer_cpu, naive_times.size(), peer / ours);
    if (temporary) std::filesystem::remove_all(folder);
    return 0;
}
