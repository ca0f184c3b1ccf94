// A libmodbus Modbus/TCP master, to drive loopwire's slave side and to read back, independently
// of loopwire, what loopwire's master side wrote.
//
// Usage:
//   libmodbus_tcp_client HOST PORT UNIT scenario
//       Writes holding registers and coils with every write function, reads them back, checks
//       that never-written tables read zero and that an unsupported function draws exception 1.
//       Prints one line per check; exits 1 on the first mismatch.
//   libmodbus_tcp_client HOST PORT UNIT read holding|input|coils|discrete ADDRESS COUNT
//       Prints the values, space separated, on one line.
// Exit status: 0 ok, 1 mismatch or Modbus error, 2 usage, 3 cannot connect.
#include <modbus/modbus.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

// Owns the libmodbus context so every exit path closes the connection.
class Connection {
public:
    Connection(const char* host, int port) : ctx_(modbus_new_tcp(host, port)) {}
    ~Connection() {
        if (ctx_ != nullptr) {
            modbus_close(ctx_);
            modbus_free(ctx_);
        }
    }
    Connection(const Connection&) = delete;
    Connection& operator=(const Connection&) = delete;

    modbus_t* get() const { return ctx_; }

private:
    modbus_t* ctx_;
};

std::string join(const std::vector<int>& values) {
    std::string text;
    for (int value : values) {
        if (!text.empty()) text += ' ';
        text += std::to_string(value);
    }
    return text;
}

// Runs one libmodbus call that returns the count it handled, or -1 with errno set.
bool call_ok(int result, const char* what) {
    if (result >= 0) return true;
    std::fprintf(stderr, "FAIL: %s: %s\n", what, modbus_strerror(errno));
    return false;
}

bool expect(const std::vector<int>& actual, const std::vector<int>& expected, const char* what) {
    if (actual != expected) {
        std::fprintf(stderr, "FAIL: %s: expected [%s], got [%s]\n", what, join(expected).c_str(), join(actual).c_str());
        return false;
    }
    std::printf("ok: %s = [%s]\n", what, join(actual).c_str());
    return true;
}

std::vector<int> read_registers(modbus_t* ctx, bool input, int address, int count, bool& ok) {
    std::vector<uint16_t> raw(static_cast<std::size_t>(count));
    const int result = input ? modbus_read_input_registers(ctx, address, count, raw.data())
                             : modbus_read_registers(ctx, address, count, raw.data());
    ok = call_ok(result, input ? "read input registers" : "read holding registers");
    return {raw.begin(), raw.end()};
}

std::vector<int> read_bits(modbus_t* ctx, bool input, int address, int count, bool& ok) {
    std::vector<uint8_t> raw(static_cast<std::size_t>(count));
    const int result = input ? modbus_read_input_bits(ctx, address, count, raw.data())
                             : modbus_read_bits(ctx, address, count, raw.data());
    ok = call_ok(result, input ? "read discrete inputs" : "read coils");
    return {raw.begin(), raw.end()};
}

int run_scenario(modbus_t* ctx) {
    bool ok = true;

    // Holding registers: FC16 with the most one request may carry (123), FC6, then FC3 with
    // the most one reply may carry (125) across both, plus the untouched neighbours.
    std::vector<uint16_t> block(123);
    for (std::size_t i = 0; i < block.size(); ++i) block[i] = static_cast<uint16_t>((i * 40503u) & 0xFFFFu);
    if (!call_ok(modbus_write_registers(ctx, 1000, static_cast<int>(block.size()), block.data()), "FC16")) return 1;
    if (!call_ok(modbus_write_register(ctx, 1010, 0xBEEF), "FC6")) return 1;
    std::vector<int> expected{0};
    expected.insert(expected.end(), block.begin(), block.end());
    expected.push_back(0);
    expected[1 + 10] = 0xBEEF;
    if (!expect(read_registers(ctx, false, 999, 125, ok), expected, "holding 999..1123") || !ok) return 1;

    // Coils: FC15 across byte boundaries, FC5 on and off, then FC1.
    const std::vector<uint8_t> pattern{1, 0, 1, 1, 0, 0, 0, 1, 1, 1, 0, 1, 0, 0, 1, 1, 1};
    if (!call_ok(modbus_write_bits(ctx, 30, static_cast<int>(pattern.size()), pattern.data()), "FC15")) return 1;
    if (!call_ok(modbus_write_bit(ctx, 31, 1), "FC5 on")) return 1;
    if (!call_ok(modbus_write_bit(ctx, 32, 0), "FC5 off")) return 1;
    std::vector<int> coils{0};
    coils.insert(coils.end(), pattern.begin(), pattern.end());
    coils.push_back(0);
    coils[1 + 1] = 1;
    coils[1 + 2] = 0;
    if (!expect(read_bits(ctx, false, 29, static_cast<int>(coils.size()), ok), coils, "coils 29..47") || !ok) return 1;

    // Nothing writes input registers or discrete inputs: zero, even where the writable
    // tables were written (the four tables are separate).
    if (!expect(read_registers(ctx, true, 1000, 12, ok), std::vector<int>(12, 0), "input 1000..1011") || !ok) return 1;
    if (!expect(read_bits(ctx, true, 30, 17, ok), std::vector<int>(17, 0), "discrete 30..46") || !ok) return 1;

    // Write-and-read registers (FC23) is not one loopwire serves: the protocol's answer is
    // exception 1, illegal function (application protocol V1.1b3, 7).
    uint16_t sent = 1;
    uint16_t got = 0;
    if (modbus_write_and_read_registers(ctx, 2000, 1, &sent, 2000, 1, &got) >= 0) {
        std::fprintf(stderr, "FAIL: FC23 succeeded; expected exception 1 (illegal function)\n");
        return 1;
    }
    if (errno != EMBXILFUN) {
        std::fprintf(stderr, "FAIL: FC23: expected exception 1 (illegal function), got: %s\n", modbus_strerror(errno));
        return 1;
    }
    std::printf("ok: FC23 draws exception 1 (illegal function)\n");
    std::printf("PASS\n");
    return 0;
}

int run_read(modbus_t* ctx, const std::string& table, int address, int count) {
    bool ok = false;
    std::vector<int> values;
    if (table == "holding" || table == "input") values = read_registers(ctx, table == "input", address, count, ok);
    else if (table == "coils" || table == "discrete") values = read_bits(ctx, table == "discrete", address, count, ok);
    else {
        std::fprintf(stderr, "unknown table '%s': holding, input, coils or discrete\n", table.c_str());
        return 2;
    }
    if (!ok) return 1;
    std::printf("%s\n", join(values).c_str());
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    const bool scenario = argc == 5 && std::strcmp(argv[4], "scenario") == 0;
    const bool read = argc == 8 && std::strcmp(argv[4], "read") == 0;
    if (!scenario && !read) {
        std::fprintf(stderr,
                     "usage: libmodbus_tcp_client HOST PORT UNIT scenario\n"
                     "       libmodbus_tcp_client HOST PORT UNIT read holding|input|coils|discrete ADDRESS COUNT\n");
        return 2;
    }
    Connection connection(argv[1], std::atoi(argv[2]));
    modbus_t* ctx = connection.get();
    if (ctx == nullptr || modbus_set_slave(ctx, std::atoi(argv[3])) != 0) {
        std::fprintf(stderr, "libmodbus_tcp_client: bad arguments: %s\n", modbus_strerror(errno));
        return 2;
    }
    // A loopback peer answers in microseconds; one second is generous and keeps failures quick.
    modbus_set_response_timeout(ctx, 1, 0);
    if (modbus_connect(ctx) != 0) {
        std::fprintf(stderr, "libmodbus_tcp_client: cannot connect to %s:%s: %s\n", argv[1], argv[2], modbus_strerror(errno));
        return 3;
    }
    if (scenario) return run_scenario(ctx);
    return run_read(ctx, argv[5], std::atoi(argv[6]), std::atoi(argv[7]));
}
