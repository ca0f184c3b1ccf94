// Throughput of the sans-I/O codecs: how many frames per second loopwire can build and take
// apart, without any I/O. The frames are the most common real traffic: a "read holding
// registers" (FC3) reply with 10 registers (a typical poll) and with 125 (the most one reply may
// carry, application protocol V1.1b3, 6.3), plus the FC3 request and the largest FC16 request.
//
// Run: build/bench/codec_bench [--benchmark_filter=Rtu]
// items_per_second is frames per second; bytes_per_second counts the frame's wire bytes.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <string>
#include <variant>

#include "codec/ascii.hpp"
#include "codec/pdu.hpp"
#include "codec/rtu.hpp"
#include "codec/tcp.hpp"

namespace {

using namespace loopwire;
using namespace loopwire::codec;

constexpr std::uint8_t unit = 17;

std::vector<std::uint16_t> register_values(std::size_t count) {
    std::vector<std::uint16_t> values(count);
    for (std::size_t i = 0; i < count; ++i) values[i] = static_cast<std::uint16_t>(0x1234 + 977 * i);
    return values;
}

Reply fc3_reply(std::size_t registers) {
    Reply reply;
    reply.function = static_cast<std::uint8_t>(FunctionCode::read_holding_registers);
    reply.count = static_cast<std::uint16_t>(registers);
    reply.values = register_values(registers);
    return reply;
}

// The benchmarks' inputs are built once, outside the timed loop; a codec that rejects them is
// a broken benchmark, reported through SkipWithError rather than timed.
Bytes fc3_reply_pdu(std::size_t registers) {
    auto pdu = encode_reply(fc3_reply(registers));
    return pdu ? *pdu : Bytes{};
}

Bytes fc16_request_pdu() {
    auto pdu = encode_request(write_multiple_registers(100, register_values(max_write_registers)));
    return pdu ? *pdu : Bytes{};
}

std::size_t frames_in(const FrameEvents& events) {
    std::size_t frames = 0;
    for (const auto& event : events) frames += std::holds_alternative<Frame>(event) ? 1u : 0u;
    return frames;
}

void count_frames(benchmark::State& state, std::size_t wire_bytes) {
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
    state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(wire_bytes));
}

// ---- PDU ----------------------------------------------------------------------------------

void PduEncodeReadReply(benchmark::State& state) {
    const Reply reply = fc3_reply(static_cast<std::size_t>(state.range(0)));
    std::size_t size = 0;
    for (auto _ : state) {
        auto pdu = encode_reply(reply);
        size = pdu->size();
        benchmark::DoNotOptimize(pdu);
    }
    count_frames(state, size);
}
BENCHMARK(PduEncodeReadReply)->Arg(10)->Arg(125);

void PduDecodeReadReply(benchmark::State& state) {
    const Bytes pdu = fc3_reply_pdu(static_cast<std::size_t>(state.range(0)));
    for (auto _ : state) {
        auto reply = decode_reply(pdu);
        benchmark::DoNotOptimize(reply);
    }
    if (!decode_reply(pdu)) state.SkipWithError("decode_reply rejected the FC3 reply");
    count_frames(state, pdu.size());
}
BENCHMARK(PduDecodeReadReply)->Arg(10)->Arg(125);

// The master's side of a poll: encode the request, then decode and match the reply to it.
void PduReadTransaction(benchmark::State& state) {
    const auto registers = static_cast<std::uint16_t>(state.range(0));
    const Request request = read_request(FunctionCode::read_holding_registers, 0, registers);
    const Bytes reply_pdu = fc3_reply_pdu(registers);
    for (auto _ : state) {
        auto sent = encode_request(request);
        benchmark::DoNotOptimize(sent);
        auto reply = decode_reply(reply_pdu);
        auto matched = match_reply(request, std::move(reply.value()));
        benchmark::DoNotOptimize(matched);
    }
    if (!match_reply(request, decode_reply(reply_pdu).value())) state.SkipWithError("match_reply rejected the reply");
    count_frames(state, reply_pdu.size());
}
BENCHMARK(PduReadTransaction)->Arg(10)->Arg(125);

// The slave's side of the largest write: decode a 123-register FC16 request.
void PduDecodeWriteMultipleRequest(benchmark::State& state) {
    const Bytes pdu = fc16_request_pdu();
    for (auto _ : state) {
        auto request = decode_request(pdu);
        benchmark::DoNotOptimize(request);
    }
    if (!decode_request(pdu)) state.SkipWithError("decode_request rejected the FC16 request");
    count_frames(state, pdu.size());
}
BENCHMARK(PduDecodeWriteMultipleRequest);

// ---- RTU ----------------------------------------------------------------------------------

void RtuCrc16(benchmark::State& state) {
    const Bytes data = fc3_reply_pdu(125);
    for (auto _ : state) benchmark::DoNotOptimize(crc16(data));
    count_frames(state, data.size());
}
BENCHMARK(RtuCrc16);

void RtuEncode(benchmark::State& state) {
    const Bytes pdu = fc3_reply_pdu(static_cast<std::size_t>(state.range(0)));
    for (auto _ : state) {
        auto frame = rtu_encode(unit, pdu);
        benchmark::DoNotOptimize(frame);
    }
    count_frames(state, pdu.size() + 3);
}
BENCHMARK(RtuEncode)->Arg(10)->Arg(125);

// Feeds `chunk` bytes at a time (0: the whole frame at once, as a pty or TCP read delivers it;
// 1: byte by byte, as a slow UART read might). Arrivals are 10 ms apart between frames, so
// every frame also starts after a silence, as on a real line.
void RtuDecode(benchmark::State& state) {
    const Bytes frame = rtu_encode(unit, fc3_reply_pdu(static_cast<std::size_t>(state.range(0))));
    const auto chunk = state.range(1) == 0 ? frame.size() : static_cast<std::size_t>(state.range(1));
    RtuDecoder decoder(Direction::reply, CharacterTiming{19200, 11});
    Instant now{};
    std::size_t frames = 0;
    for (auto _ : state) {
        now += std::chrono::milliseconds(10);
        for (std::size_t at = 0; at < frame.size(); at += chunk) {
            const ByteView piece = ByteView(frame).subspan(at, std::min(chunk, frame.size() - at));
            FrameEvents events = decoder.feed(piece, now);
            frames += frames_in(events);
            benchmark::DoNotOptimize(events);
        }
    }
    if (frames != static_cast<std::size_t>(state.iterations())) state.SkipWithError("the decoder did not deliver one frame per frame fed");
    count_frames(state, frame.size());
}
BENCHMARK(RtuDecode)->ArgNames({"registers", "chunk"})->Args({10, 0})->Args({125, 0})->Args({125, 1});

// ---- ASCII --------------------------------------------------------------------------------

void AsciiEncode(benchmark::State& state) {
    const Bytes pdu = fc3_reply_pdu(static_cast<std::size_t>(state.range(0)));
    std::size_t size = 0;
    for (auto _ : state) {
        auto frame = ascii_encode(unit, pdu);
        size = frame.size();
        benchmark::DoNotOptimize(frame);
    }
    count_frames(state, size);
}
BENCHMARK(AsciiEncode)->Arg(10)->Arg(125);

void AsciiDecode(benchmark::State& state) {
    const Bytes frame = ascii_encode(unit, fc3_reply_pdu(static_cast<std::size_t>(state.range(0))));
    AsciiDecoder decoder;
    std::size_t frames = 0;
    for (auto _ : state) {
        FrameEvents events = decoder.feed(frame);
        frames += frames_in(events);
        benchmark::DoNotOptimize(events);
    }
    if (frames != static_cast<std::size_t>(state.iterations())) state.SkipWithError("the decoder did not deliver one frame per frame fed");
    count_frames(state, frame.size());
}
BENCHMARK(AsciiDecode)->Arg(10)->Arg(125);

// ---- Modbus/TCP (MBAP) --------------------------------------------------------------------

void MbapEncode(benchmark::State& state) {
    const Bytes pdu = fc3_reply_pdu(static_cast<std::size_t>(state.range(0)));
    std::uint16_t transaction = 0;
    for (auto _ : state) {
        auto frame = mbap_encode(++transaction, unit, pdu);
        benchmark::DoNotOptimize(frame);
    }
    count_frames(state, pdu.size() + 7);
}
BENCHMARK(MbapEncode)->Arg(10)->Arg(125);

void MbapDecode(benchmark::State& state) {
    const Bytes frame = mbap_encode(1, unit, fc3_reply_pdu(static_cast<std::size_t>(state.range(0))));
    MbapDecoder decoder;
    std::size_t frames = 0;
    for (auto _ : state) {
        auto decoded = decoder.feed(frame);
        frames += decoded ? decoded->size() : 0;
        benchmark::DoNotOptimize(decoded);
    }
    if (frames != static_cast<std::size_t>(state.iterations())) state.SkipWithError("the decoder did not deliver one frame per frame fed");
    count_frames(state, frame.size());
}
BENCHMARK(MbapDecode)->Arg(10)->Arg(125);

}  // namespace
