// Modbus PDU encoding, decoding and validation for function codes 1-6, 15 and 16.
// Field layouts follow the Modbus Application Protocol Specification V1.1b3, section 6; the
// device manuals (AC20 "Function code N" sections, ramp/soak §4.7, TC10 §3.1-3.3) print the
// same layouts with example frames that tests/codec/rtu_test.cpp replays.
#include "codec/pdu.hpp"

#include <algorithm>
#include <string_view>

namespace loopwire::codec {

namespace {

constexpr std::uint8_t exception_flag = 0x80;
constexpr std::uint16_t coil_on_value = 0xFF00;   // V1.1b3 6.5: FF00h requests ON
constexpr std::uint16_t coil_off_value = 0x0000;  // ... and 0000h OFF; anything else is illegal
// The byte count field is one byte, and a PDU is at most 253 bytes (V1.1b3 4.1), so a reply
// carries at most 250 data bytes: 2000 bits or 125 registers.
constexpr std::size_t max_reply_data_bytes = 250;
// Fixed PDU sizes: function + two 16-bit fields (FC1-6 requests, FC5/6/15/16 replies),
// function + one byte (exception replies), and the FC15/16 request header before the data.
constexpr std::size_t two_field_pdu_size = 5;
constexpr std::size_t exception_pdu_size = 2;
constexpr std::size_t write_multiple_header_size = 6;

std::string_view direction_word(Direction direction) {
    return direction == Direction::request ? "request" : "reply";
}

// "FC16 request" — the prefix of every validation message, so a reader knows which PDU failed.
std::string pdu_label(std::uint8_t function, Direction direction) {
    return "FC" + std::to_string(function) + " " + std::string(direction_word(direction));
}

std::string hex16(std::uint16_t value) {
    static constexpr char digits[] = "0123456789ABCDEF";
    std::string out(4, '0');
    for (int i = 3; i >= 0; --i) {
        out[static_cast<std::size_t>(i)] = digits[value & 0x0F];
        value = static_cast<std::uint16_t>(value >> 4);
    }
    return out + "h";
}

bool is_bit_function(std::uint8_t function) { return function == 1 || function == 2; }
bool is_register_read_function(std::uint8_t function) { return function == 3 || function == 4; }
bool is_read_function(std::uint8_t function) {
    return is_bit_function(function) || is_register_read_function(function);
}
bool is_multiple_write_function(std::uint8_t function) { return function == 15 || function == 16; }

std::uint16_t read_quantity_limit(std::uint8_t function) {
    return is_bit_function(function) ? max_read_bits : max_read_registers;
}
std::uint16_t write_quantity_limit(std::uint8_t function) {
    return function == 15 ? max_write_bits : max_write_registers;
}

std::size_t packed_byte_count(std::size_t bits) { return (bits + 7) / 8; }

// Data bytes a quantity implies for FC1/2/15 (bits, packed) and FC3/4/16 (registers).
std::size_t data_bytes_for_quantity(std::uint8_t function, std::size_t quantity) {
    const bool bits = is_bit_function(function) || function == 15;
    return bits ? packed_byte_count(quantity) : quantity * 2;
}

// Each check returns an explanation when it fails, so callers can attach the PDU label and the
// error kind that fits their side (usage for encoding, malformed for decoding).
using Problem = std::optional<std::string>;

Problem check_quantity(std::uint16_t quantity, std::uint16_t limit) {
    if (quantity >= 1 && quantity <= limit) return std::nullopt;
    return "quantity " + std::to_string(quantity) + " outside 1.." + std::to_string(limit);
}

// V1.1b3 6.x: the addressed block must stay inside the 16-bit address space.
Problem check_address_range(std::uint16_t address, std::uint16_t quantity) {
    if (quantity == 0 || std::uint32_t{address} + quantity - 1 <= 0xFFFF) return std::nullopt;
    return "address " + std::to_string(address) + " + quantity " + std::to_string(quantity) +
           " runs past FFFFh";
}

Problem check_bit_states(const std::vector<std::uint16_t>& states) {
    for (std::size_t i = 0; i < states.size(); ++i) {
        if (states[i] > 1) {
            return "bit state " + std::to_string(states[i]) + " at index " + std::to_string(i) +
                   " is not 0 or 1";
        }
    }
    return std::nullopt;
}

// "1 byte", "5 bytes".
std::string byte_quantity(std::size_t count) {
    return std::to_string(count) + (count == 1 ? " byte" : " bytes");
}

Problem check_exact_size(std::size_t actual, std::size_t expected) {
    if (actual == expected) return std::nullopt;
    return byte_quantity(actual) + ", expected " + std::to_string(expected);
}

Problem byte_count_problem(std::size_t byte_count, std::uint16_t quantity, std::size_t expected) {
    return "byte count " + std::to_string(byte_count) + " does not match quantity " +
           std::to_string(quantity) + " (expected " + std::to_string(expected) + ")";
}

Problem first_problem(std::initializer_list<Problem> problems) {
    for (const Problem& problem : problems) {
        if (problem) return problem;
    }
    return std::nullopt;
}

Error usage_error(std::uint8_t function, Direction direction, const std::string& problem) {
    return make_error(ErrorKind::usage, pdu_label(function, direction) + ": " + problem);
}
Error malformed_error(std::uint8_t function, Direction direction, const std::string& problem) {
    return make_error(ErrorKind::malformed, pdu_label(function, direction) + ": " + problem);
}
Error mismatch_error(std::uint8_t function, const std::string& problem) {
    return make_error(ErrorKind::mismatch, pdu_label(function, Direction::reply) + ": " + problem);
}

Error unsupported_function_error(ErrorKind kind, std::uint8_t function) {
    return make_error(kind, "unsupported function code " + std::to_string(function) +
                                " (loopwire handles 1, 2, 3, 4, 5, 6, 15 and 16)");
}

Error empty_pdu_error(Direction direction) {
    return make_error(ErrorKind::malformed,
                      "empty " + std::string(direction_word(direction)) + " PDU: no function code");
}

Bytes pdu_with_two_fields(std::uint8_t function, std::uint16_t first, std::uint16_t second) {
    Bytes out{function};
    append_be16(out, first);
    append_be16(out, second);
    return out;
}

std::uint16_t coil_wire_value(std::uint16_t state) { return state ? coil_on_value : coil_off_value; }

Problem check_coil_wire_value(std::uint16_t value) {
    if (value == coil_on_value || value == coil_off_value) return std::nullopt;
    return "coil value " + hex16(value) + " is neither 0000h (off) nor FF00h (on)";
}

std::vector<std::uint16_t> read_registers(ByteView data) {
    std::vector<std::uint16_t> registers;
    registers.reserve(data.size() / 2);
    for (std::size_t at = 0; at + 1 < data.size(); at += 2) registers.push_back(read_be16(data, at));
    return registers;
}

void append_registers(Bytes& out, const std::vector<std::uint16_t>& registers) {
    out.reserve(out.size() + 2 * registers.size());  // one allocation, not one per doubling
    for (std::uint16_t value : registers) append_be16(out, value);
}

// ---- requests ---------------------------------------------------------------------------

Result<Bytes> encode_read_request(const Request& request) {
    const std::uint8_t fc = request.function;
    if (!request.values.empty()) {
        return usage_error(fc, Direction::request,
                           "a read carries no values (got " + std::to_string(request.values.size()) + ")");
    }
    if (auto problem = first_problem({check_quantity(request.count, read_quantity_limit(fc)),
                                      check_address_range(request.address, request.count)})) {
        return usage_error(fc, Direction::request, *problem);
    }
    return pdu_with_two_fields(fc, request.address, request.count);
}

Result<Bytes> encode_single_write_request(const Request& request) {
    const std::uint8_t fc = request.function;
    if (request.values.size() != 1 || request.count != 1) {
        return usage_error(fc, Direction::request,
                           "a single write carries exactly one value (count " +
                               std::to_string(request.count) + ", " +
                               std::to_string(request.values.size()) + " values)");
    }
    if (fc == 6) return pdu_with_two_fields(fc, request.address, request.values[0]);
    if (auto problem = check_bit_states(request.values)) {
        return usage_error(fc, Direction::request, *problem);
    }
    return pdu_with_two_fields(fc, request.address, coil_wire_value(request.values[0]));
}

Result<Bytes> encode_multiple_write_request(const Request& request) {
    const std::uint8_t fc = request.function;
    if (request.count != request.values.size()) {
        return usage_error(fc, Direction::request,
                           "count " + std::to_string(request.count) + " differs from the " +
                               std::to_string(request.values.size()) + " values given");
    }
    Problem problem = first_problem({check_quantity(request.count, write_quantity_limit(fc)),
                                     check_address_range(request.address, request.count)});
    if (!problem && fc == 15) problem = check_bit_states(request.values);
    if (problem) return usage_error(fc, Direction::request, *problem);

    Bytes out = pdu_with_two_fields(fc, request.address, request.count);
    out.push_back(static_cast<std::uint8_t>(data_bytes_for_quantity(fc, request.count)));
    if (fc == 15) {
        const Bytes packed = pack_bits(request.values);
        out.insert(out.end(), packed.begin(), packed.end());
    } else {
        append_registers(out, request.values);
    }
    return out;
}

Result<Request> decode_read_request(ByteView pdu) {
    const std::uint8_t fc = pdu[0];
    if (auto problem = check_exact_size(pdu.size(), two_field_pdu_size)) {
        return malformed_error(fc, Direction::request, *problem);
    }
    Request request{fc, read_be16(pdu, 1), read_be16(pdu, 3), {}};
    if (auto problem = first_problem({check_quantity(request.count, read_quantity_limit(fc)),
                                      check_address_range(request.address, request.count)})) {
        return malformed_error(fc, Direction::request, *problem);
    }
    return request;
}

Result<Request> decode_single_write_request(ByteView pdu) {
    const std::uint8_t fc = pdu[0];
    if (auto problem = check_exact_size(pdu.size(), two_field_pdu_size)) {
        return malformed_error(fc, Direction::request, *problem);
    }
    const std::uint16_t value = read_be16(pdu, 3);
    if (fc == 5) {
        if (auto problem = check_coil_wire_value(value)) {
            return malformed_error(fc, Direction::request, *problem);
        }
        return Request{fc, read_be16(pdu, 1), 1, {static_cast<std::uint16_t>(value == coil_on_value)}};
    }
    return Request{fc, read_be16(pdu, 1), 1, {value}};
}

Result<Request> decode_multiple_write_request(ByteView pdu) {
    const std::uint8_t fc = pdu[0];
    if (pdu.size() < write_multiple_header_size) {
        return malformed_error(fc, Direction::request,
                               byte_quantity(pdu.size()) +
                                   ", too short for the 6-byte header (function, address, "
                                   "quantity, byte count)");
    }
    const std::uint16_t address = read_be16(pdu, 1);
    const std::uint16_t quantity = read_be16(pdu, 3);
    const std::size_t byte_count = pdu[5];
    if (auto problem = first_problem({check_quantity(quantity, write_quantity_limit(fc)),
                                      check_address_range(address, quantity)})) {
        return malformed_error(fc, Direction::request, *problem);
    }
    const std::size_t implied = data_bytes_for_quantity(fc, quantity);
    if (byte_count != implied) {
        return malformed_error(fc, Direction::request, *byte_count_problem(byte_count, quantity, implied));
    }
    if (pdu.size() != write_multiple_header_size + byte_count) {
        return malformed_error(fc, Direction::request,
                               byte_quantity(pdu.size()) + ", expected " +
                                   std::to_string(write_multiple_header_size + byte_count) +
                                   " (6 + byte count " + std::to_string(byte_count) + ")");
    }
    const ByteView data = pdu.subspan(write_multiple_header_size);
    auto values = fc == 15 ? unpack_bits(data, quantity) : read_registers(data);
    return Request{fc, address, quantity, std::move(values)};
}

// ---- replies ----------------------------------------------------------------------------

Result<Bytes> encode_exception_reply(const Reply& reply) {
    if (reply.function == 0 || (reply.function & exception_flag) != 0) {
        return make_error(ErrorKind::usage, "exception reply: function " +
                                                std::to_string(reply.function) +
                                                " outside 1..127");
    }
    return Bytes{static_cast<std::uint8_t>(reply.function | exception_flag), reply.exception_code};
}

// FC1-4 replies: `count` is not on the wire, the values say how many (Reply in pdu.hpp).
Result<Bytes> encode_read_reply(const Reply& reply) {
    const std::uint8_t fc = reply.function;
    const std::uint16_t limit = read_quantity_limit(fc);
    if (reply.values.empty() || reply.values.size() > limit) {
        return usage_error(fc, Direction::reply,
                           std::to_string(reply.values.size()) + " values, outside 1.." +
                               std::to_string(limit));
    }
    if (is_bit_function(fc)) {
        if (auto problem = check_bit_states(reply.values)) return usage_error(fc, Direction::reply, *problem);
    }
    const std::size_t data_bytes = data_bytes_for_quantity(fc, reply.values.size());
    Bytes out;
    out.reserve(2 + data_bytes);  // the reply's one allocation
    out.push_back(fc);
    out.push_back(static_cast<std::uint8_t>(data_bytes));
    if (is_bit_function(fc)) {
        const Bytes packed = pack_bits(reply.values);
        out.insert(out.end(), packed.begin(), packed.end());
    } else {
        append_registers(out, reply.values);
    }
    return out;
}

Result<Bytes> encode_single_write_reply(const Reply& reply) {
    const std::uint8_t fc = reply.function;
    if (reply.values.size() != 1) {
        return usage_error(fc, Direction::reply,
                           "the echo carries exactly one value (got " +
                               std::to_string(reply.values.size()) + ")");
    }
    if (fc == 6) return pdu_with_two_fields(fc, reply.address, reply.values[0]);
    if (auto problem = check_bit_states(reply.values)) return usage_error(fc, Direction::reply, *problem);
    return pdu_with_two_fields(fc, reply.address, coil_wire_value(reply.values[0]));
}

Result<Bytes> encode_multiple_write_reply(const Reply& reply) {
    const std::uint8_t fc = reply.function;
    if (auto problem = first_problem({check_quantity(reply.count, write_quantity_limit(fc)),
                                      check_address_range(reply.address, reply.count)})) {
        return usage_error(fc, Direction::reply, *problem);
    }
    return pdu_with_two_fields(fc, reply.address, reply.count);
}

Result<Reply> decode_exception_reply(ByteView pdu) {
    const auto function = static_cast<std::uint8_t>(pdu[0] & ~exception_flag);
    if (auto problem = check_exact_size(pdu.size(), exception_pdu_size)) {
        return make_error(ErrorKind::malformed,
                          "exception reply to function " + std::to_string(function) + ": " + *problem);
    }
    if (function == 0) {
        return make_error(ErrorKind::malformed, "exception reply for function 0, which does not exist");
    }
    Reply reply;
    reply.function = function;
    reply.kind = ReplyKind::exception;
    reply.exception_code = pdu[1];
    return reply;
}

Result<Reply> decode_read_reply(ByteView pdu) {
    const std::uint8_t fc = pdu[0];
    if (pdu.size() < 2) return malformed_error(fc, Direction::reply, "1 byte, too short (no byte count)");
    const std::size_t byte_count = pdu[1];
    const bool bits = is_bit_function(fc);
    // V1.1b3 6.1-6.4: at least one data item; registers come in whole 2-byte words.
    if (byte_count == 0 || byte_count > max_reply_data_bytes || (!bits && byte_count % 2 != 0)) {
        return malformed_error(fc, Direction::reply,
                               "byte count " + std::to_string(byte_count) + " is not " +
                                   (bits ? "in 1..250" : "an even number in 2..250"));
    }
    if (auto problem = check_exact_size(pdu.size(), 2 + byte_count)) {
        return malformed_error(fc, Direction::reply, *problem + " (2 + byte count " +
                                                         std::to_string(byte_count) + ")");
    }
    const ByteView data = pdu.subspan(2);
    Reply reply;
    reply.function = fc;
    reply.values = bits ? unpack_bits(data, byte_count * 8) : read_registers(data);
    reply.count = static_cast<std::uint16_t>(reply.values.size());
    return reply;
}

Result<Reply> decode_write_reply(ByteView pdu) {
    const std::uint8_t fc = pdu[0];
    if (auto problem = check_exact_size(pdu.size(), two_field_pdu_size)) {
        return malformed_error(fc, Direction::reply, *problem);
    }
    Reply reply;
    reply.function = fc;
    reply.address = read_be16(pdu, 1);
    const std::uint16_t second = read_be16(pdu, 3);
    if (is_multiple_write_function(fc)) {
        if (auto problem = first_problem({check_quantity(second, write_quantity_limit(fc)),
                                          check_address_range(reply.address, second)})) {
            return malformed_error(fc, Direction::reply, *problem);
        }
        reply.count = second;
        return reply;
    }
    if (fc == 5) {
        if (auto problem = check_coil_wire_value(second)) {
            return malformed_error(fc, Direction::reply, *problem);
        }
        reply.values = {static_cast<std::uint16_t>(second == coil_on_value)};
    } else {
        reply.values = {second};
    }
    reply.count = 1;
    return reply;
}

// ---- matching ---------------------------------------------------------------------------

Result<Reply> match_read_reply(const Request& request, Reply reply) {
    const std::uint8_t fc = request.function;
    const std::size_t expected_bytes = data_bytes_for_quantity(fc, request.count);
    const std::size_t actual_bytes = is_bit_function(fc) ? packed_byte_count(reply.values.size())
                                                         : reply.values.size() * 2;
    if (actual_bytes != expected_bytes) {
        return mismatch_error(fc, *byte_count_problem(actual_bytes, request.count, expected_bytes));
    }
    // The reply does not carry the address or the quantity; fill them in from the request so
    // callers see which items the values belong to. Bit padding goes (V1.1b3 6.1).
    reply.values.resize(request.count);
    reply.count = request.count;
    reply.address = request.address;
    return reply;
}

Problem echo_problem(std::string_view field, std::uint32_t echoed, std::uint32_t sent) {
    if (echoed == sent) return std::nullopt;
    return std::string(field) + " echo " + std::to_string(echoed) + " differs from the " +
           std::to_string(sent) + " requested";
}

Result<Reply> match_write_reply(const Request& request, Reply reply) {
    const std::uint8_t fc = request.function;
    Problem problem = echo_problem("address", reply.address, request.address);
    if (!problem && is_multiple_write_function(fc)) {
        problem = echo_problem("quantity", reply.count, request.count);
    }
    if (!problem && !is_multiple_write_function(fc)) {
        if (reply.values.size() != 1 || request.values.size() != 1) {
            problem = "value echo missing";
        } else {
            problem = echo_problem("value", reply.values[0], request.values[0]);
        }
    }
    if (problem) return mismatch_error(fc, *problem);
    return reply;
}

}  // namespace

bool is_supported_function(std::uint8_t function) {
    return (function >= 1 && function <= 6) || is_multiple_write_function(function);
}

std::string function_name(std::uint8_t function) {
    switch (function) {
        case 1: return "read coils";
        case 2: return "read discrete inputs";
        case 3: return "read holding registers";
        case 4: return "read input registers";
        case 5: return "write single coil";
        case 6: return "write single register";
        case 15: return "write multiple coils";
        case 16: return "write multiple registers";
        default: return "function " + std::to_string(function);
    }
}

// Modbus application protocol V1.1b3, 7 "MODBUS Exception Responses": every code the
// specification defines; others are device-specific (profiles name them).
std::optional<std::string> exception_name(std::uint8_t code) {
    switch (code) {
        case 1: return "illegal function";
        case 2: return "illegal data address";
        case 3: return "illegal data value";
        case 4: return "server device failure";
        case 5: return "acknowledge";
        case 6: return "server device busy";
        case 8: return "memory parity error";
        case 0x0A: return "gateway path unavailable";
        case 0x0B: return "gateway target device failed to respond";
        default: return std::nullopt;
    }
}

std::string describe_exception(std::uint8_t code) {
    std::string text = std::to_string(code);
    if (auto name = exception_name(code)) text += " (" + *name + ")";
    return text;
}

Request read_request(FunctionCode function, std::uint16_t address, std::uint16_t count) {
    return Request{static_cast<std::uint8_t>(function), address, count, {}};
}

Request write_single_coil(std::uint16_t address, bool on) {
    return Request{static_cast<std::uint8_t>(FunctionCode::write_single_coil), address, 1,
                   {static_cast<std::uint16_t>(on ? 1 : 0)}};
}

Request write_single_register(std::uint16_t address, std::uint16_t value) {
    return Request{static_cast<std::uint8_t>(FunctionCode::write_single_register), address, 1, {value}};
}

Request write_multiple_coils(std::uint16_t address, std::vector<std::uint16_t> states) {
    const auto count = static_cast<std::uint16_t>(states.size());
    return Request{static_cast<std::uint8_t>(FunctionCode::write_multiple_coils), address, count,
                   std::move(states)};
}

Request write_multiple_registers(std::uint16_t address, std::vector<std::uint16_t> values) {
    const auto count = static_cast<std::uint16_t>(values.size());
    return Request{static_cast<std::uint8_t>(FunctionCode::write_multiple_registers), address, count,
                   std::move(values)};
}

Reply exception_reply(std::uint8_t function, std::uint8_t code) {
    Reply reply;
    reply.function = function;
    reply.kind = ReplyKind::exception;
    reply.exception_code = code;
    return reply;
}

Result<Bytes> encode_request(const Request& request) {
    const std::uint8_t fc = request.function;
    if (!is_supported_function(fc)) return unsupported_function_error(ErrorKind::usage, fc);
    if (is_read_function(fc)) return encode_read_request(request);
    if (is_multiple_write_function(fc)) return encode_multiple_write_request(request);
    return encode_single_write_request(request);
}

Result<Bytes> encode_reply(const Reply& reply) {
    if (reply.kind == ReplyKind::exception) return encode_exception_reply(reply);
    const std::uint8_t fc = reply.function;
    if (!is_supported_function(fc)) return unsupported_function_error(ErrorKind::usage, fc);
    if (is_read_function(fc)) return encode_read_reply(reply);
    if (is_multiple_write_function(fc)) return encode_multiple_write_reply(reply);
    return encode_single_write_reply(reply);
}

Result<Request> decode_request(ByteView pdu) {
    if (pdu.empty()) return empty_pdu_error(Direction::request);
    const std::uint8_t fc = pdu[0];
    if (!is_supported_function(fc)) return unsupported_function_error(ErrorKind::malformed, fc);
    if (is_read_function(fc)) return decode_read_request(pdu);
    if (is_multiple_write_function(fc)) return decode_multiple_write_request(pdu);
    return decode_single_write_request(pdu);
}

Result<Reply> decode_reply(ByteView pdu) {
    if (pdu.empty()) return empty_pdu_error(Direction::reply);
    const std::uint8_t fc = pdu[0];
    if ((fc & exception_flag) != 0) return decode_exception_reply(pdu);
    if (!is_supported_function(fc)) return unsupported_function_error(ErrorKind::malformed, fc);
    if (is_read_function(fc)) return decode_read_reply(pdu);
    return decode_write_reply(pdu);
}

std::optional<std::size_t> expected_pdu_length(Direction direction, ByteView prefix) {
    if (prefix.empty()) return std::nullopt;
    const std::uint8_t fc = prefix[0];
    // Only a reply can be an exception (V1.1b3 7): function | 80h + one code byte.
    if (direction == Direction::reply && (fc & exception_flag) != 0) return exception_pdu_size;
    if (!is_supported_function(fc)) return 0;

    constexpr std::size_t byte_count_index_request = 5;
    constexpr std::size_t byte_count_index_reply = 1;
    if (direction == Direction::request) {
        if (!is_multiple_write_function(fc)) return two_field_pdu_size;
        if (prefix.size() <= byte_count_index_request) return std::nullopt;
        return write_multiple_header_size + prefix[byte_count_index_request];
    }
    if (!is_read_function(fc)) return two_field_pdu_size;
    if (prefix.size() <= byte_count_index_reply) return std::nullopt;
    return 2 + std::size_t{prefix[byte_count_index_reply]};
}

Result<Reply> match_reply(const Request& request, Reply reply) {
    if (reply.function != request.function) {
        return make_error(ErrorKind::mismatch,
                          "reply is for function " + std::to_string(reply.function) + " (" +
                              function_name(reply.function) + "), the request was function " +
                              std::to_string(request.function) + " (" +
                              function_name(request.function) + ")");
    }
    // Exceptions are valid answers; the session layer turns them into ErrorKind::exception.
    if (reply.kind == ReplyKind::exception) return reply;
    if (!is_supported_function(request.function)) {
        return unsupported_function_error(ErrorKind::usage, request.function);
    }
    if (is_read_function(request.function)) return match_read_reply(request, std::move(reply));
    return match_write_reply(request, std::move(reply));
}

Bytes pack_bits(const std::vector<std::uint16_t>& states) {
    Bytes packed(packed_byte_count(states.size()), 0);
    for (std::size_t i = 0; i < states.size(); ++i) {
        if (states[i] != 0) packed[i / 8] = static_cast<std::uint8_t>(packed[i / 8] | (1u << (i % 8)));
    }
    return packed;
}

std::vector<std::uint16_t> unpack_bits(ByteView packed, std::size_t count) {
    // Never read past the bytes given: a short buffer yields fewer states, not garbage.
    const std::size_t available = std::min(count, packed.size() * 8);
    std::vector<std::uint16_t> states(available);
    for (std::size_t i = 0; i < available; ++i) {
        states[i] = static_cast<std::uint16_t>((static_cast<unsigned>(packed[i / 8]) >> (i % 8)) & 1u);
    }
    return states;
}

}  // namespace loopwire::codec
