#pragma once
// A plain Modbus data model: all four tables, 65536 entries each, zero at start, all writable.
// What `loopwire simulate` serves for a unit that has no device profile.
#include <array>
#include <cstdint>
#include <mutex>
#include <vector>

#include "codec/table.hpp"
#include "session/unit_handler.hpp"

namespace loopwire::session {

using codec::Table;

class RegisterBank final : public RequestHandler {
public:
    RegisterBank();

    // Direct access for whoever hosts the bank (tests, demos): thread-safe.
    std::uint16_t get(Table table, std::uint16_t address) const;
    void set(Table table, std::uint16_t address, std::uint16_t value);

protected:
    codec::Reply serve(const codec::Request& request) override;

private:
    std::vector<std::uint16_t>& table(Table which) { return tables_[static_cast<std::size_t>(which)]; }
    codec::Reply read(Table which, const codec::Request& request);
    void write(Table which, std::uint16_t address, const std::vector<std::uint16_t>& values);

    mutable std::mutex mutex_;
    std::array<std::vector<std::uint16_t>, 4> tables_;
};

}  // namespace loopwire::session
