#include "client/identity_check.hpp"

#include <cstdint>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

// Compared as int16: the profiles write identification values as the manuals print them.
bool identification_holds(const IdentificationCheck& check, std::uint16_t raw) {
    return static_cast<std::int16_t>(raw) == static_cast<std::int16_t>(check.equals);
}

bool refused_as_absent(const std::optional<Error>& error) {
    return error && error->kind == ErrorKind::exception && (error->code == 1 || error->code == 2);
}

}  // namespace

std::vector<const Parameter*> identification_words(const Profile& profile) {
    std::vector<const Parameter*> words;
    for (const auto& check : profile.identification) {
        if (const auto* p = profile.find(check.parameter)) words.push_back(p);
    }
    return words;
}

IdentityVerdict judge_identity(const Profile& profile, const ReadReport& report) {
    for (const auto& check : profile.identification) {
        const auto* p = profile.find(check.parameter);
        if (p == nullptr) continue;
        if (const auto raw = report.raw.find(p->name); raw != report.raw.end()) {
            if (identification_holds(check, raw->second)) continue;
            return {IdentityVerdict::Kind::wrong,
                    fmt::format("its {} (word {}) reads {} where the {} profile expects {}", p->name, p->address,
                                static_cast<std::int16_t>(raw->second), profile.id, check.equals)};
        }
        // Illegal function or address: the unit has no such word, so it is another device.
        if (refused_as_absent(report.first_error)) {
            return {IdentityVerdict::Kind::wrong, fmt::format("it refuses {} (word {}), which the {} profile reads to identify it: {}",
                                                              p->name, p->address, profile.id, report.first_error->message)};
        }
        return {IdentityVerdict::Kind::unknown,
                report.first_error ? report.first_error->message : fmt::format("{} was not read", p->name)};
    }
    return {IdentityVerdict::Kind::holds, {}};
}

}  // namespace loopwire::device
