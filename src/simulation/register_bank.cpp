#include "simulation/register_bank.hpp"

namespace loopwire::session {

RegisterBank::RegisterBank() {
    for (auto& t : tables_) t.assign(0x10000, 0);
}

std::uint16_t RegisterBank::get(Table which, std::uint16_t address) const {
    std::lock_guard lock(mutex_);
    return tables_[static_cast<std::size_t>(which)][address];
}

void RegisterBank::set(Table which, std::uint16_t address, std::uint16_t value) {
    std::lock_guard lock(mutex_);
    table(which)[address] = value;
}

codec::Reply RegisterBank::read(Table which, const codec::Request& request) {
    const auto& source = table(which);
    codec::Reply reply{request.function, codec::ReplyKind::normal, 0, request.address, request.count, {}};
    reply.values.assign(source.begin() + request.address, source.begin() + request.address + request.count);
    return reply;
}

void RegisterBank::write(Table which, std::uint16_t address, const std::vector<std::uint16_t>& values) {
    std::copy(values.begin(), values.end(), table(which).begin() + address);
}

codec::Reply RegisterBank::serve(const codec::Request& request) {
    std::lock_guard lock(mutex_);
    using codec::FunctionCode;
    if (const auto read_table = codec::table_read_by(request.function)) return read(*read_table, request);
    switch (static_cast<FunctionCode>(request.function)) {
        case FunctionCode::read_coils:
        case FunctionCode::read_discrete_inputs:
        case FunctionCode::read_holding_registers:
        case FunctionCode::read_input_registers:
            break;  // answered above
        case FunctionCode::write_single_coil:
        case FunctionCode::write_multiple_coils:
            write(Table::coils, request.address, request.values);
            break;
        case FunctionCode::write_single_register:
        case FunctionCode::write_multiple_registers:
            write(Table::holding_registers, request.address, request.values);
            break;
    }
    // Write replies echo the request: address and value (FC5/6) or address and quantity (FC15/16).
    codec::Reply reply{request.function, codec::ReplyKind::normal, 0, request.address, request.count, {}};
    if (request.function == 5 || request.function == 6) reply.values = request.values;
    return reply;
}

}  // namespace loopwire::session
