#include "codec/tcp.hpp"

#include <algorithm>
#include <cassert>
#include <optional>
#include <string>

namespace loopwire::codec {

namespace {

// Modbus Messaging on TCP/IP V1.0b, 3.1.3: transaction id (2), protocol id (2), length (2),
// unit id (1). The length counts the unit id and the PDU.
constexpr std::size_t mbap_header_size = 7;
constexpr std::size_t length_field_end = 6;
constexpr std::uint16_t modbus_protocol_id = 0;
constexpr std::uint16_t min_length = 2;    // unit + function code
constexpr std::uint16_t max_length = 254;  // unit + 253-byte PDU (application protocol 4.1)

std::string hex16(std::uint16_t value) {
    constexpr char digits[] = "0123456789ABCDEF";
    std::string out(4, '0');
    for (int i = 3; i >= 0; --i) {
        out[static_cast<std::size_t>(i)] = digits[value & 0x0F];
        value = static_cast<std::uint16_t>(value >> 4);
    }
    return out;
}

// Header fields are checked as soon as their bytes are in, so a peer that speaks something
// else is refused on its first read rather than after it has sent a "frame" of garbage.
std::optional<Error> check_header(ByteView header) {
    if (header.size() >= 4) {
        const std::uint16_t protocol = read_be16(header, 2);
        if (protocol != modbus_protocol_id) {
            return make_error(ErrorKind::malformed,
                              "MBAP protocol id " + hex16(protocol) + "h (" + std::to_string(protocol) +
                                  ") is not 0 (Modbus): the peer does not speak Modbus TCP; close "
                                  "the connection");
        }
    }
    if (header.size() >= length_field_end) {
        const std::uint16_t length = read_be16(header, 4);
        if (length < min_length || length > mbap_max_trusted_length) {
            return make_error(ErrorKind::malformed,
                              "MBAP length " + std::to_string(length) + " is outside " +
                                  std::to_string(min_length) + ".." + std::to_string(mbap_max_trusted_length) +
                                  " (unit id + PDU of at most 253 bytes; up to " +
                                  std::to_string(mbap_max_trusted_length) +
                                  " is skipped and refused): the stream cannot be "
                                  "resynchronised; close the connection");
        }
    }
    return std::nullopt;
}

Frame make_frame(ByteView adu) {
    Frame frame;
    frame.transaction = read_be16(adu, 0);
    frame.unit = adu[6];
    frame.pdu.assign(adu.begin() + mbap_header_size, adu.end());
    frame.raw.assign(adu.begin(), adu.end());
    return frame;
}

}  // namespace

void mbap_append(Bytes& out, std::uint16_t transaction, std::uint8_t unit, ByteView pdu) {
    // A PDU longer than 253 bytes is a programming error: nobody may send one.
    assert(pdu.size() + 1 <= max_length);
    append_be16(out, transaction);
    append_be16(out, modbus_protocol_id);
    append_be16(out, static_cast<std::uint16_t>(pdu.size() + 1));
    out.push_back(unit);
    out.insert(out.end(), pdu.begin(), pdu.end());
}

Bytes mbap_encode(std::uint16_t transaction, std::uint8_t unit, ByteView pdu) {
    Bytes out;
    out.reserve(mbap_header_size + pdu.size());
    mbap_append(out, transaction, unit, pdu);
    return out;
}

Result<std::vector<Frame>> MbapDecoder::feed(ByteView bytes) {
    if (broken_) return *broken_;
    buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
    std::vector<Frame> frames;
    std::size_t start = 0;
    while (true) {
        const ByteView rest = ByteView(buffer_).subspan(start);
        // The bad header stays buffered; the error repeats on every later feed(), until reset().
        if (auto error = check_header(rest.first(std::min(rest.size(), length_field_end)))) {
            buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start));
            broken_ = std::move(*error);
            if (frames.empty()) return *broken_;
            return frames;  // answered before the connection closes (broken() says so)
        }
        if (rest.size() < length_field_end) break;
        const std::size_t adu_size = length_field_end + read_be16(rest, 4);
        if (rest.size() < adu_size) break;
        frames.push_back(make_frame(rest.first(adu_size)));
        start += adu_size;
    }
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start));
    return frames;
}

}  // namespace loopwire::codec
