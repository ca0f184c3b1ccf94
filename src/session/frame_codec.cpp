#include "session/frame_codec.hpp"

#include "codec/ascii.hpp"
#include "codec/rtu.hpp"
#include "codec/tcp.hpp"
#include "session/linking_frame_codec.hpp"

namespace loopwire::session {
namespace {

using codec::FrameEvents;

class RtuFrameCodec final : public FrameCodec {
public:
    RtuFrameCodec(codec::Direction direction, codec::CharacterTiming timing)
        : decoder_(direction, timing) {}

    Result<Bytes> encode(std::uint8_t unit, ByteView pdu, std::uint16_t) override {
        return codec::rtu_encode(unit, pdu);
    }
    Result<FrameEvents> feed(ByteView bytes, Instant arrival) override {
        return decoder_.feed(bytes, arrival);
    }
    FrameEvents flush(Instant now) override { return decoder_.flush(now); }
    std::optional<Instant> flush_deadline() const override { return decoder_.silence_deadline(); }
    void reset() override { decoder_.reset(); }

private:
    codec::RtuDecoder decoder_;
};

class AsciiFrameCodec final : public FrameCodec {
public:
    explicit AsciiFrameCodec(unsigned data_bits) : decoder_(data_bits) {}

    Result<Bytes> encode(std::uint8_t unit, ByteView pdu, std::uint16_t) override {
        return codec::ascii_encode(unit, pdu);
    }
    Result<FrameEvents> feed(ByteView bytes, Instant) override { return decoder_.feed(bytes); }
    void reset() override { decoder_.reset(); }

private:
    codec::AsciiDecoder decoder_;
};

class MbapFrameCodec final : public FrameCodec {
public:
    Result<Bytes> encode(std::uint8_t unit, ByteView pdu, std::uint16_t transaction) override {
        return codec::mbap_encode(transaction, unit, pdu);
    }
    Result<FrameEvents> feed(ByteView bytes, Instant) override {
        auto frames = decoder_.feed(bytes);
        if (!frames) return frames.error();
        FrameEvents events;
        events.reserve(frames->size());
        for (auto& frame : *frames) events.emplace_back(std::move(frame));
        return events;
    }
    std::optional<Error> stream_error() const override { return decoder_.broken(); }
    void reset() override { decoder_.reset(); }

private:
    codec::MbapDecoder decoder_;
};

codec::CharacterTiming timing_of(const transport::LinkUrl& link) {
    if (link.framing == transport::Framing::rtu_over_tcp) {
        // A serial device server hides the line's timing: frames are delimited by length, and
        // the silence rule only has to clean up after noise. Assume a fast line.
        return codec::CharacterTiming{115200, 11};
    }
    return codec::CharacterTiming{link.serial.baud, link.serial.bits_per_character()};
}

}  // namespace

std::unique_ptr<FrameCodec> make_frame_codec(const transport::LinkUrl& link,
                                             codec::Direction direction, bool linking_ram_only) {
    switch (link.framing) {
        case transport::Framing::rtu:
        case transport::Framing::rtu_over_tcp:
            return std::make_unique<RtuFrameCodec>(direction, timing_of(link));
        case transport::Framing::ascii:
            return std::make_unique<AsciiFrameCodec>(link.serial.data_bits);
        case transport::Framing::tcp:
            return std::make_unique<MbapFrameCodec>();
        case transport::Framing::linking:
            return make_linking_frame_codec(direction, linking_ram_only);
    }
    return nullptr;
}

}  // namespace loopwire::session
