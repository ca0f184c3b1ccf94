#include "app/dump_document.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include <fmt/format.h>

#include "app/value_format.hpp"

namespace loopwire::app {

std::vector<const device::Parameter*> dumped_parameters(const device::Profile& profile) {
    std::vector<const device::Parameter*> list;
    for (const auto& p : profile.parameters) {
        if (p.readable) list.push_back(&p);
    }
    return list;
}

namespace {

Result<nlohmann::ordered_json> parameter_entry(const device::ParameterReading& reading, const device::RawValues& known) {
    const auto& p = *reading.parameter;
    if (!reading.value) return make_error(ErrorKind::mismatch, fmt::format("{} was not read: {}", p.name, reading.error));
    auto text = device::format_value(p, *reading.value, known);
    if (!text) return text.error();
    auto entry = value_json(p, *reading.value);
    return nlohmann::ordered_json{{"value", entry["value"]}, {"text", *text}, {"unit", p.unit},
                                  {"raw", nlohmann::ordered_json::array({reading.value->raw})},
                                  {"status", reading.value->status}, {"writable", p.writable}};
}

nlohmann::ordered_json identification_of(const device::Profile& profile, const device::RawValues& raw) {
    nlohmann::ordered_json identification = nlohmann::ordered_json::object();
    for (const auto& name : profile.identification_report) {
        if (auto word = raw.find(name); word != raw.end()) identification[name] = word->second;
    }
    return identification;
}

}  // namespace

Result<nlohmann::ordered_json> dump_document(const device::DeviceAddress& device, const DumpHeader& header,
                                             const device::ReadReport& report) {
    const auto& profile = *device.profile;
    nlohmann::ordered_json parameters = nlohmann::ordered_json::object();
    for (const auto& reading : report.readings) {
        auto entry = parameter_entry(reading, report.raw);
        if (!entry) return entry.error();
        parameters[reading.parameter->name] = std::move(*entry);
    }
    nlohmann::ordered_json document{{"format", "loopwire-dump"}, {"version", 1}, {"profile", profile.id}, {"unit", device.unit},
                                    {"link", header.link}, {"time", header.time}};
    if (!header.numbering.empty()) document["numbering"] = header.numbering;
    document["identification"] = identification_of(profile, report.raw);
    document["parameters"] = std::move(parameters);
    return document;
}

namespace {

Error file_error(const std::string& path, const char* what) {
    return make_error(ErrorKind::usage, fmt::format("cannot write {}: {} failed: {}", path, what, std::strerror(errno)));
}

bool write_all(int fd, const std::string& text) {
    std::size_t done = 0;
    while (done < text.size()) {
        const auto written = ::write(fd, text.data() + done, text.size() - done);
        if (written < 0 && errno == EINTR) continue;
        if (written <= 0) return false;
        done += static_cast<std::size_t>(written);
    }
    return true;
}

// The rename is only durable once the directory entry is on disk too.
void sync_directory(const std::string& directory) {
    const int fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY);
    if (fd < 0) return;
    ::fsync(fd);
    ::close(fd);
}

// Fills the open temporary file and flushes it to disk.
Result<void> fill(int fd, const std::string& path, const std::string& text) {
    if (::fchmod(fd, 0644) != 0) return file_error(path, "chmod");
    if (!write_all(fd, text)) return file_error(path, "write");
    if (::fsync(fd) != 0) return file_error(path, "fsync");
    return {};
}

}  // namespace

Result<void> write_file_atomically(const std::string& path, const std::string& text) {
    const auto parent = std::filesystem::path(path).parent_path();
    const std::string directory = parent.empty() ? "." : parent.string();
    std::string temporary = path + ".tmp-XXXXXX";
    const int fd = ::mkstemp(temporary.data());
    if (fd < 0) return file_error(path, "creating a temporary file");
    Result<void> done = fill(fd, path, text);
    if (::close(fd) != 0 && done) done = file_error(path, "close");
    if (done && ::rename(temporary.c_str(), path.c_str()) != 0) done = file_error(path, "rename");
    if (!done) {
        ::unlink(temporary.c_str());
        return done;
    }
    sync_directory(directory);
    return {};
}

}  // namespace loopwire::app
