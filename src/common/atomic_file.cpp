#include "common/atomic_file.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>

#include <fmt/format.h>

namespace loopwire {

namespace {

Error file_error(const std::string& path, const char* what) {
    return make_error(ErrorKind::usage, fmt::format("cannot write {}: {} failed: {}; check that the folder exists and is writable",
                                                    path, what, std::strerror(errno)));
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

}  // namespace loopwire
