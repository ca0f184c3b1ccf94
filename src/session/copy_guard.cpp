#include "session/copy_guard.hpp"

#include <algorithm>
#include <array>
#include <vector>

namespace loopwire::session {

void CopyGuard::forget_before(Instant at) {
    while (!frames_.empty() && frames_.front().at < at) frames_.pop_front();
    while (!damaged_.empty() && damaged_.front().at < at) damaged_.pop_front();
}

void CopyGuard::heard_damaged(ByteView bytes, ByteView request, Instant at) {
    if (bytes.empty()) return;
    forget_before(at - window_);
    if (damaged_.size() == most_damaged_runs) damaged_.pop_front();
    damaged_.push_back({Bytes(bytes.begin(), bytes.end()), Bytes(request.begin(), request.end()), at});
}

// The damaged runs within the window, joined in the order they came: a frame cut in two by a
// pause arrives as two runs. A match that lies only in runs heard while this same request was
// awaited is the request's own answer, damaged on an earlier try.
std::optional<CopyGuard::Earlier> CopyGuard::among_damaged(ByteView raw, ByteView request, Instant recent) const {
    Bytes joined;
    std::vector<std::size_t> starts;  // where each run kept begins in `joined`
    std::vector<const HeardFrame*> runs;
    for (const auto& run : damaged_) {
        if (run.at < recent) continue;
        starts.push_back(joined.size());
        runs.push_back(&run);
        joined.insert(joined.end(), run.raw.begin(), run.raw.end());
    }
    if (raw.empty()) return std::nullopt;
    for (auto at = std::search(joined.begin(), joined.end(), raw.begin(), raw.end()); at != joined.end();
         at = std::search(at + 1, joined.end(), raw.begin(), raw.end())) {
        const auto first = static_cast<std::size_t>(at - joined.begin());
        const auto last = first + raw.size() - 1;
        for (std::size_t i = 0; i < runs.size(); ++i) {
            const std::size_t end = i + 1 < runs.size() ? starts[i + 1] : joined.size();
            if (starts[i] > last || end <= first) continue;
            if (!std::ranges::equal(runs[i]->request, request)) return Earlier{runs[i]->at, false};
        }
    }
    return std::nullopt;
}

void CopyGuard::heard(ByteView raw, ByteView request, Instant at) {
    forget_before(at - window_);
    if (frames_.size() == most_frames) frames_.pop_front();
    frames_.push_back({Bytes(raw.begin(), raw.end()), Bytes(request.begin(), request.end()), at});
}

void CopyGuard::sent(std::uint8_t unit, ByteView pdu, Instant at) {
    if (pdu.empty() || reads_only(pdu[0])) return;
    auto& writes = writes_[unit];
    while (!writes.empty() && (writes.front().at < at - window_ || writes.size() >= most_writes_per_unit)) writes.pop_front();
    writes.push_back({at, codec::written_span(pdu)});
    forget_answers(unit, writes.back().span);
}

void CopyGuard::forget_answers(std::uint8_t unit, const std::optional<codec::DataSpan>& written) {
    std::erase_if(answers_, [&](const auto& answer) {
        if (unit != 0 && answer.first.first != unit) return false;
        const auto read = codec::read_span(answer.first.second);
        return !written || !read || written->overlaps(*read);
    });
}

void CopyGuard::answered(std::uint8_t unit, ByteView request, ByteView raw) {
    if (request.empty() || !reads_only(request[0])) return;
    auto key = std::make_pair(unit, Bytes(request.begin(), request.end()));
    if (auto found = answers_.find(key); found != answers_.end()) {
        found->second.assign(raw.begin(), raw.end());
        return;
    }
    if (answers_.size() >= most_answers) answers_.erase(answers_.begin());
    answers_.emplace(std::move(key), Bytes(raw.begin(), raw.end()));
}

// Whether a request that may change what `read` reads of the unit (sent to it, or broadcast)
// went out at or after `at`: a write sent at the instant a frame was heard follows it (the master
// sends once the line is quiet). A write elsewhere in the unit is not counted (a read of other
// registers answers the same after it); one whose reach is not known is.
bool CopyGuard::written_over(std::uint8_t unit, const codec::DataSpan& read, Instant at) const {
    return std::ranges::any_of(std::array<std::uint8_t, 2>{unit, std::uint8_t{0}}, [&](std::uint8_t to) {
        const auto found = writes_.find(to);
        if (found == writes_.end()) return false;
        return std::ranges::any_of(found->second, [&](const SentWrite& write) {
            return write.at >= at && (!write.span || write.span->overlaps(read));
        });
    });
}

std::optional<CopyGuard::Earlier> CopyGuard::copy_of(ByteView raw, ByteView request, std::uint8_t unit, Instant now,
                                                     bool doubt_own_answers) const {
    if (const auto last = answers_.find(std::make_pair(unit, Bytes(request.begin(), request.end())));
        !doubt_own_answers && last != answers_.end() && std::ranges::equal(last->second, raw)) {
        return std::nullopt;
    }
    const Instant recent = now - window_;
    const auto read = codec::read_span(request);
    std::optional<Earlier> another;      // the same bytes for another request, or for none
    std::optional<Earlier> before_write;  // for this read, before a write over what it reads
    for (auto seen = frames_.rbegin(); seen != frames_.rend() && seen->at >= recent; ++seen) {
        if (!std::ranges::equal(seen->raw, raw)) continue;
        if (doubt_own_answers || !std::ranges::equal(seen->request, request)) {
            if (!another) another = Earlier{seen->at, false};
            continue;
        }
        // The device answered this same request so, with nothing written over it since (or it is
        // a write's echo): whatever frame these bytes are, the value is the device's answer.
        if (!read || !written_over(unit, *read, seen->at)) return std::nullopt;
        if (!before_write) before_write = Earlier{seen->at, true};
    }
    if (!another) another = among_damaged(raw, request, recent);
    return another ? another : before_write;
}

void CopyGuard::confirm(ByteView raw, ByteView request, Instant since) {
    for (auto seen = frames_.rbegin(); seen != frames_.rend() && seen->at >= since; ++seen) {
        if (seen->request.empty() && std::ranges::equal(seen->raw, raw)) seen->request.assign(request.begin(), request.end());
    }
}

}  // namespace loopwire::session
