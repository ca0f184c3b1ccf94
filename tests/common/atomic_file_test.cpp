// Atomic file writes (common/atomic_file.hpp): what is at the path decides what "replace"
// means; a device node, a FIFO or a symbolic link is never replaced by a regular file.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <sstream>

#include "common/atomic_file.hpp"

namespace loopwire {
namespace {

namespace fs = std::filesystem;

class AtomicWrite : public ::testing::Test {
protected:
    void SetUp() override {
        std::string pattern = (fs::temp_directory_path() / "loopwire-atomic-test-XXXXXX").string();
        ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
        dir = pattern;
    }
    void TearDown() override { fs::remove_all(dir); }
    std::size_t entries() const {
        return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
    }
    static std::string contents(const fs::path& path) {
        std::ifstream in(path);
        std::stringstream text;
        text << in.rdbuf();
        return text.str();
    }
    static mode_t mode_of(const fs::path& path) {
        struct stat status {};
        EXPECT_EQ(::lstat(path.c_str(), &status), 0) << path;
        return status.st_mode;
    }
    fs::path dir;
};

// Sets the umask for one test and puts the previous one back.
class UmaskFor {
public:
    explicit UmaskFor(mode_t mask) : previous_(::umask(mask)) {}
    ~UmaskFor() { ::umask(previous_); }

private:
    mode_t previous_;
};

TEST_F(AtomicWrite, ReplacesTheFileWholeAndLeavesNoTemporaryBehind) {
    const auto path = (dir / "unit3.json").string();
    ASSERT_TRUE(write_file_atomically(path, "old\n"));
    ASSERT_TRUE(write_file_atomically(path, "{\"new\":true}\n"));
    EXPECT_EQ(contents(path), "{\"new\":true}\n");
    EXPECT_EQ(entries(), 1u);
}

TEST_F(AtomicWrite, AnUnwritableDestinationFailsWithoutLeavingAFile) {
    const auto path = (dir / "missing-dir" / "unit3.json").string();
    auto written = write_file_atomically(path, "x");
    ASSERT_FALSE(written);
    EXPECT_NE(written.error().message.find(path), std::string::npos);
    EXPECT_EQ(entries(), 0u);
    EXPECT_FALSE(check_writable_atomically(path));
}

TEST_F(AtomicWrite, ADirectoryIsRefusedAndUntouched) {
    const auto path = dir / "taken";
    fs::create_directory(path);
    auto written = write_file_atomically(path.string(), "x");
    ASSERT_FALSE(written);
    EXPECT_NE(written.error().message.find("is a directory"), std::string::npos) << written.error().message;
    EXPECT_FALSE(check_writable_atomically(path.string()));
    EXPECT_TRUE(fs::is_directory(path));
    EXPECT_EQ(entries(), 1u);  // no temporary left either
}

TEST_F(AtomicWrite, NewFilesHonourTheUmaskAndTheModeAsked) {
    UmaskFor mask(027);
    ASSERT_TRUE(write_file_atomically((dir / "ordinary").string(), "x", ordinary_file_mode));
    EXPECT_EQ(mode_of(dir / "ordinary") & 07777, 0640u);
    ASSERT_TRUE(write_file_atomically((dir / "private").string(), "x", private_file_mode));
    EXPECT_EQ(mode_of(dir / "private") & 07777, 0600u);
    UmaskFor strict(077);
    ASSERT_TRUE(write_file_atomically((dir / "strict").string(), "x", ordinary_file_mode));
    EXPECT_EQ(mode_of(dir / "strict") & 07777, 0600u);
}

TEST_F(AtomicWrite, AReplacedFileKeepsItsModeAndOwner) {
    const auto path = dir / "kept";
    ASSERT_TRUE(write_file_atomically(path.string(), "old"));
    ASSERT_EQ(::chmod(path.c_str(), 0604), 0);
    // As root the owner can be anyone: make it someone else, to see it kept.
    const bool root = ::geteuid() == 0;
    if (root) {
        ASSERT_EQ(::chown(path.c_str(), 4321, 4322), 0);
    }
    ASSERT_TRUE(write_file_atomically(path.string(), "new", private_file_mode));
    EXPECT_EQ(contents(path), "new");
    struct stat status {};
    ASSERT_EQ(::stat(path.c_str(), &status), 0);
    EXPECT_EQ(status.st_mode & 07777, 0604u);
    if (root) {
        EXPECT_EQ(status.st_uid, 4321u);
        EXPECT_EQ(status.st_gid, 4322u);
    }
}

TEST_F(AtomicWrite, ASymbolicLinkIsFollowedAndItsTargetReplaced) {
    fs::create_directory(dir / "real");
    const auto target = dir / "real" / "state.json";
    ASSERT_TRUE(write_file_atomically(target.string(), "old"));
    ASSERT_EQ(::chmod(target.c_str(), 0640), 0);
    fs::create_symlink("real/state.json", dir / "relative-link");   // relative to the link's folder
    fs::create_symlink(dir / "relative-link", dir / "chained-link");  // a link to a link
    ASSERT_TRUE(write_file_atomically((dir / "chained-link").string(), "new"));
    EXPECT_TRUE(fs::is_symlink(dir / "relative-link"));
    EXPECT_TRUE(fs::is_symlink(dir / "chained-link"));
    EXPECT_EQ(contents(target), "new");
    EXPECT_EQ(mode_of(target) & 07777, 0640u);
    EXPECT_EQ(entries(), 3u);  // real/, two links: the temporary was in real/ and is gone
    EXPECT_EQ(std::distance(fs::directory_iterator(dir / "real"), fs::directory_iterator()), 1);
}

TEST_F(AtomicWrite, ADanglingLinkCreatesItsTarget) {
    fs::create_symlink("made-by-write", dir / "link");
    ASSERT_TRUE(write_file_atomically((dir / "link").string(), "x"));
    EXPECT_TRUE(fs::is_symlink(dir / "link"));
    EXPECT_EQ(contents(dir / "made-by-write"), "x");
}

TEST_F(AtomicWrite, ALinkLoopIsRefused) {
    fs::create_symlink("b", dir / "a");
    fs::create_symlink("a", dir / "b");
    auto written = write_file_atomically((dir / "a").string(), "x");
    ASSERT_FALSE(written);
    EXPECT_TRUE(fs::is_symlink(dir / "a"));
}

TEST_F(AtomicWrite, AFifoIsWrittenIntoNotReplaced) {
    const auto fifo = dir / "pipe";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    auto reader = std::async(std::launch::async, [&] { return contents(fifo); });  // opening blocks until the writer comes
    ASSERT_TRUE(write_file_atomically(fifo.string(), "through the pipe\n"));
    ASSERT_EQ(reader.wait_for(std::chrono::seconds(10)), std::future_status::ready) << "the reader never saw the end";
    EXPECT_EQ(reader.get(), "through the pipe\n");
    EXPECT_TRUE(S_ISFIFO(mode_of(fifo)));
    EXPECT_EQ(entries(), 1u);
}

TEST_F(AtomicWrite, ACharacterDeviceIsWrittenIntoNotReplaced) {
    // A private copy of /dev/null (char 1:3), so a regression cannot destroy the real one.
    const auto node = dir / "null";
    if (::mknod(node.c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0) {
        GTEST_SKIP() << "cannot make a device node here (not root?)";
    }
    ASSERT_TRUE(write_file_atomically(node.string(), "discarded"));
    EXPECT_TRUE(S_ISCHR(mode_of(node)));
    EXPECT_TRUE(check_writable_atomically(node.string()));
    EXPECT_EQ(entries(), 1u);
}

TEST_F(AtomicWrite, StaleTemporariesOfTheSameFileAreRemoved) {
    const auto path = dir / "state.json";
    ASSERT_TRUE(write_file_atomically(path.string(), "{}"));
    for (const char* name : {"state.json.tmp-Ab3xY9", "state.json.tmp-000000"}) std::ofstream(dir / name) << "half";
    // Not ours: another file's temporary, another suffix length, a directory, a user's file.
    for (const char* name : {"other.json.tmp-Ab3xY9", "state.json.tmp-Ab3xY", "state.json.tmp-notes.txt"}) std::ofstream(dir / name) << "keep";
    fs::create_directory(dir / "state.json.tmp-DIRxx1");
    const auto removed = remove_stale_temporaries(path.string());
    EXPECT_EQ(removed.size(), 2u);
    EXPECT_FALSE(fs::exists(dir / "state.json.tmp-Ab3xY9"));
    EXPECT_FALSE(fs::exists(dir / "state.json.tmp-000000"));
    EXPECT_TRUE(fs::exists(dir / "other.json.tmp-Ab3xY9"));
    EXPECT_TRUE(fs::exists(dir / "state.json.tmp-Ab3xY"));
    EXPECT_TRUE(fs::exists(dir / "state.json.tmp-notes.txt"));
    EXPECT_TRUE(fs::is_directory(dir / "state.json.tmp-DIRxx1"));
    EXPECT_EQ(contents(path), "{}");
}

}  // namespace
}  // namespace loopwire
