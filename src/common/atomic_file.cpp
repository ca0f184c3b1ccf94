#include "common/atomic_file.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstring>
#include <random>
#include <string_view>

#include <fmt/format.h>

namespace loopwire {

namespace {

constexpr std::string_view temporary_infix = ".tmp-";
constexpr std::size_t temporary_suffix_length = 6;
constexpr std::string_view temporary_alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789";
// Linux follows at most 40 links in one lookup (path_resolution(7)); more is a loop.
constexpr int most_link_hops = 40;

Error file_error(const std::string& path, const char* what, int error_number) {
    return make_error(ErrorKind::usage, fmt::format("cannot write {}: {} failed: {}; check that the folder exists and is writable",
                                                    path, what, std::strerror(error_number)));
}

Error refused(const std::string& path, const std::string& what) {
    return make_error(ErrorKind::usage, fmt::format("cannot write {}: {}; it was left untouched: name a regular file instead", path, what));
}

std::string directory_of(const std::string& path) {
    const auto slash = path.rfind('/');
    if (slash == std::string::npos) return ".";
    if (slash == 0) return "/";
    return path.substr(0, slash);
}

std::string base_name_of(const std::string& path) {
    const auto slash = path.rfind('/');
    return slash == std::string::npos ? path : path.substr(slash + 1);
}

// The path a chain of symbolic links ends at, whether or not that exists (a dangling link
// names the file to create). Relative link contents are relative to the link's directory.
Result<std::string> final_target(const std::string& path) {
    std::string current = path;
    for (int hop = 0; hop <= most_link_hops; ++hop) {
        struct stat status {};
        if (::lstat(current.c_str(), &status) != 0) {
            if (errno == ENOENT) return current;
            return file_error(path, "examining the path", errno);
        }
        if (!S_ISLNK(status.st_mode)) return current;
        std::string target(PATH_MAX, '\0');
        const auto length = ::readlink(current.c_str(), target.data(), target.size());
        if (length < 0) return file_error(path, "reading the symbolic link", errno);
        target.resize(static_cast<std::size_t>(length));
        current = target.starts_with('/') ? target : directory_of(current) + "/" + target;
    }
    return refused(path, fmt::format("more than {} symbolic links in a row (a loop?)", most_link_hops));
}

const char* kind_of(mode_t mode) {
    if (S_ISDIR(mode)) return "a directory";
    if (S_ISBLK(mode)) return "a block device";
    if (S_ISSOCK(mode)) return "a socket";
    return "not a regular file";
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

// A FIFO or character device: written into as a shell redirection would (see the header).
Result<void> write_in_place(const std::string& path, const std::string& text) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_NOCTTY | O_CLOEXEC);
    if (fd < 0) return file_error(path, "open", errno);
    struct stat status {};
    // Between the look and the open something else may have appeared at the path: only the
    // kinds that are written in place are.
    if (::fstat(fd, &status) != 0 || !(S_ISFIFO(status.st_mode) || S_ISCHR(status.st_mode))) {
        ::close(fd);
        return refused(path, "it changed while being opened");
    }
    Result<void> done;
    if (!write_all(fd, text)) done = file_error(path, "write", errno);
    if (::close(fd) != 0 && done) done = file_error(path, "close", errno);
    return done;
}

// The rename is only durable once the directory entry is on disk too.
void sync_directory(const std::string& directory) {
    const int fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) return;
    ::fsync(fd);
    ::close(fd);
}

// Creates `<target>.tmp-XXXXXX` with `mode` (less the umask, applied by the kernel); our own
// mkstemp, as mkstemp always creates 0600 and cannot honour a wider umask.
Result<int> create_temporary(const std::string& target, mode_t mode, std::string& temporary) {
    std::random_device entropy;
    std::uniform_int_distribution<std::size_t> pick(0, temporary_alphabet.size() - 1);
    for (int attempt = 0; attempt < 100; ++attempt) {
        temporary = target + std::string(temporary_infix);
        for (std::size_t i = 0; i < temporary_suffix_length; ++i) temporary += temporary_alphabet[pick(entropy)];
        const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, mode);
        if (fd >= 0) return fd;
        if (errno != EEXIST) return file_error(target, "creating a temporary file", errno);
    }
    return file_error(target, "creating a temporary file", EEXIST);
}

// Fills the open temporary file, gives it the replaced file's mode and owner, and flushes it.
Result<void> fill(int fd, const std::string& path, const std::string& text, const struct stat* replaced) {
    if (replaced) {
        // Owner first: chown clears set-user-ID bits, which the chmod then puts back.
        if (::fchown(fd, replaced->st_uid, replaced->st_gid) != 0) {
            return make_error(ErrorKind::usage, fmt::format("cannot write {}: it belongs to user {} group {}, and the new "
                                                            "version could not be given that owner ({}); write it as that "
                                                            "user, or remove it first",
                                                            path, replaced->st_uid, replaced->st_gid, std::strerror(errno)));
        }
        if (::fchmod(fd, replaced->st_mode & 07777) != 0) return file_error(path, "chmod", errno);
    }
    if (!write_all(fd, text)) return file_error(path, "write", errno);
    if (::fsync(fd) != 0) return file_error(path, "fsync", errno);
    return {};
}

bool is_our_temporary_of(std::string_view entry, std::string_view base) {
    if (entry.size() != base.size() + temporary_infix.size() + temporary_suffix_length) return false;
    if (!entry.starts_with(base) || entry.substr(base.size(), temporary_infix.size()) != temporary_infix) return false;
    const auto suffix = entry.substr(base.size() + temporary_infix.size());
    return suffix.find_first_not_of(temporary_alphabet) == std::string_view::npos;
}

}  // namespace

Result<void> check_writable_atomically(const std::string& path) {
    struct stat status {};
    if (::stat(path.c_str(), &status) == 0) {
        if (S_ISFIFO(status.st_mode) || S_ISCHR(status.st_mode)) {
            if (::access(path.c_str(), W_OK) != 0) return file_error(path, "checking write permission", errno);
            return {};
        }
        if (!S_ISREG(status.st_mode)) return refused(path, fmt::format("it is {}", kind_of(status.st_mode)));
    }
    auto target = final_target(path);
    if (!target) return target.error();
    // The temporary is what a write creates; creating one (and removing it) is the only test
    // that also holds for root, read-only file systems and full inode tables.
    std::string temporary;
    auto fd = create_temporary(*target, private_file_mode, temporary);
    if (!fd) return fd.error();
    ::close(*fd);
    ::unlink(temporary.c_str());
    return {};
}

Result<void> write_file_atomically(const std::string& path, const std::string& text, mode_t new_file_mode) {
    // stat() follows every link, magic ones too (/dev/stdout -> /proc/self/fd/1 -> pipe:[..]):
    // what is finally there decides how it is written.
    struct stat status {};
    if (::stat(path.c_str(), &status) == 0) {
        if (S_ISFIFO(status.st_mode) || S_ISCHR(status.st_mode)) return write_in_place(path, text);
        if (!S_ISREG(status.st_mode)) return refused(path, fmt::format("it is {}", kind_of(status.st_mode)));
    }
    auto target = final_target(path);
    if (!target) return target.error();
    struct stat replaced {};
    const bool exists = ::lstat(target->c_str(), &replaced) == 0;
    if (exists && !S_ISREG(replaced.st_mode)) return refused(path, fmt::format("it is {}", kind_of(replaced.st_mode)));
    std::string temporary;
    auto fd = create_temporary(*target, new_file_mode, temporary);
    if (!fd) return fd.error();
    Result<void> done = fill(*fd, path, text, exists ? &replaced : nullptr);
    if (::close(*fd) != 0 && done) done = file_error(path, "close", errno);
    if (done && ::rename(temporary.c_str(), target->c_str()) != 0) done = file_error(path, "rename", errno);
    if (!done) {
        ::unlink(temporary.c_str());
        return done;
    }
    sync_directory(directory_of(*target));
    return {};
}

std::vector<std::string> remove_stale_temporaries(const std::string& path) {
    std::vector<std::string> removed;
    auto target = final_target(path);
    if (!target) return removed;
    const std::string directory = directory_of(*target);
    const std::string base = base_name_of(*target);
    DIR* listing = ::opendir(directory.c_str());
    if (!listing) return removed;
    while (const dirent* entry = ::readdir(listing)) {
        if (!is_our_temporary_of(entry->d_name, base)) continue;
        const std::string candidate = directory + "/" + entry->d_name;
        struct stat status {};
        if (::lstat(candidate.c_str(), &status) != 0 || !S_ISREG(status.st_mode) || status.st_uid != ::geteuid()) continue;
        if (::unlink(candidate.c_str()) == 0) removed.push_back(candidate);
    }
    ::closedir(listing);
    return removed;
}

}  // namespace loopwire
