// Files a user names for reading are examined before they are opened (common/regular_file.hpp):
// a FIFO, a directory or a device is refused without waiting, a regular file is read whole.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/regular_file.hpp"

namespace loopwire {
namespace {

namespace fs = std::filesystem;

class RegularFile : public ::testing::Test {
protected:
    void SetUp() override {
        std::string pattern = (fs::temp_directory_path() / "loopwire-regular-file-XXXXXX").string();
        ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
        dir = pattern;
    }
    void TearDown() override { fs::remove_all(dir); }
    fs::path dir;
};

TEST_F(RegularFile, ARegularFileIsReadWhole) {
    std::ofstream(dir / "secret", std::ios::binary) << "s3cret\nsecond line\n";
    EXPECT_EQ(not_a_regular_file(dir / "secret"), std::nullopt);
    auto text = read_regular_file(dir / "secret", 1024);
    ASSERT_TRUE(text) << text.error().message;
    EXPECT_EQ(*text, "s3cret\nsecond line\n");
}

// Opening a FIFO for reading would wait for a writer: were it opened, this test would hang
// until ctest's timeout instead of failing.
TEST_F(RegularFile, AFifoIsRefusedWithoutBeingOpened) {
    const fs::path fifo = dir / "pipe";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    EXPECT_EQ(not_a_regular_file(fifo), "is a FIFO (named pipe), not a regular file");
    auto text = read_regular_file(fifo, 1024);
    ASSERT_FALSE(text);
    EXPECT_EQ(text.error().kind, ErrorKind::usage);
    EXPECT_EQ(text.error().message, "\"" + fifo.string() + "\" is a FIFO (named pipe), not a regular file");
}

TEST_F(RegularFile, DirectoriesDevicesAndAbsentFilesSayWhatTheyAre) {
    EXPECT_EQ(not_a_regular_file(dir), "is a directory, not a regular file");
    EXPECT_EQ(not_a_regular_file("/dev/null"), "is a character device, not a regular file");
    EXPECT_EQ(not_a_regular_file(dir / "absent"), "does not exist");
    auto absent = read_regular_file(dir / "absent", 1024);
    ASSERT_FALSE(absent);
    EXPECT_EQ(absent.error().message, "\"" + (dir / "absent").string() + "\" does not exist");
}

TEST_F(RegularFile, AFileLargerThanTheBoundIsRefusedUnread) {
    std::ofstream(dir / "large", std::ios::binary) << std::string(2048, 'x');
    auto text = read_regular_file(dir / "large", 1024);
    ASSERT_FALSE(text);
    EXPECT_NE(text.error().message.find("is too large: 2048 bytes (at most 1024 expected)"), std::string::npos)
        << text.error().message;
}

TEST_F(RegularFile, ASymbolicLinkToARegularFileIsFollowed) {
    std::ofstream(dir / "target", std::ios::binary) << "pem";
    fs::create_symlink(dir / "target", dir / "link");
    auto text = read_regular_file(dir / "link", 1024);
    ASSERT_TRUE(text) << text.error().message;
    EXPECT_EQ(*text, "pem");
}

}  // namespace
}  // namespace loopwire
