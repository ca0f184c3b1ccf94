#include "profile/name_matching.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <optional>
#include <set>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

struct FoldedLetter {
    std::string_view utf8;
    char ascii;
};

// The manuals' letters that have no key on a keyboard, and what a user types instead
// (profiles/NOTES.md, "ASCII for non-ASCII mnemonic letters").
constexpr std::array<FoldedLetter, 2> folded_letters{{
    {"\xC3\xB1", 'm'},  // ñ: the AC20 manual's rendering of the display's 'm'
    {"\xC3\x91", 'm'},  // Ñ
}};

std::optional<FoldedLetter> letter_at(std::string_view text, std::size_t at) {
    for (const auto& letter : folded_letters) {
        if (text.substr(at, letter.utf8.size()) == letter.utf8) return letter;
    }
    return std::nullopt;
}

struct Candidate {
    std::string label;
    std::size_t distance;
    bool contains;  // the folded entry contains the folded typed text
    std::size_t order;
};

std::string parameter_label(const Parameter& parameter) {
    return parameter.mnemonic.empty() ? parameter.name : fmt::format("{} ({})", parameter.name, parameter.mnemonic);
}

// The words a parameter is known by: its name, its mnemonic and the aliases naming it.
std::vector<std::string_view> words_of(const Profile& profile, const Parameter& parameter) {
    std::vector<std::string_view> words{parameter.name};
    if (!parameter.mnemonic.empty()) words.push_back(parameter.mnemonic);
    for (const auto& [alias, name] : profile.aliases) {
        if (name == parameter.name) words.push_back(alias);
    }
    return words;
}

Candidate measure(std::string label, const std::string& typed, const std::vector<std::string_view>& words, std::size_t order) {
    Candidate candidate{std::move(label), std::string::npos, false, order};
    for (const auto word : words) {
        const std::string folded = folded_name(word);
        candidate.distance = std::min(candidate.distance, edit_distance(typed, folded));
        candidate.contains = candidate.contains || (typed.size() >= 3 && folded.find(typed) != std::string::npos);
    }
    return candidate;
}

std::vector<Candidate> candidates_of(const Profile& profile, const std::string& typed) {
    std::vector<Candidate> candidates;
    std::set<std::string, std::less<>> groups;
    for (const Parameter& parameter : profile.parameters) {
        candidates.push_back(measure(parameter_label(parameter), typed, words_of(profile, parameter), candidates.size()));
        if (!parameter.group.empty() && groups.insert(parameter.group).second) {
            candidates.push_back(measure("group " + parameter.group, typed, {parameter.group}, candidates.size()));
        }
    }
    return candidates;
}

}  // namespace

std::string folded_name(std::string_view text) {
    std::string folded;
    folded.reserve(text.size());
    for (std::size_t at = 0; at < text.size();) {
        if (const auto letter = letter_at(text, at)) {
            folded += letter->ascii;
            at += letter->utf8.size();
            continue;
        }
        folded += static_cast<char>(std::tolower(static_cast<unsigned char>(text[at])));
        ++at;
    }
    return folded;
}

bool same_name(std::string_view typed, std::string_view listed) { return folded_name(typed) == folded_name(listed); }

std::size_t edit_distance(std::string_view a, std::string_view b) {
    const std::string x = folded_name(a);
    const std::string y = folded_name(b);
    // Three rows of the (|x|+1) x (|y|+1) table: the swap of neighbours looks two rows back.
    std::vector<std::size_t> before(y.size() + 1), previous(y.size() + 1), current(y.size() + 1);
    for (std::size_t j = 0; j <= y.size(); ++j) previous[j] = j;
    for (std::size_t i = 1; i <= x.size(); ++i) {
        current[0] = i;
        for (std::size_t j = 1; j <= y.size(); ++j) {
            const std::size_t substitution = x[i - 1] == y[j - 1] ? 0 : 1;
            current[j] = std::min({previous[j] + 1, current[j - 1] + 1, previous[j - 1] + substitution});
            if (i > 1 && j > 1 && x[i - 1] == y[j - 2] && x[i - 2] == y[j - 1]) current[j] = std::min(current[j], before[j - 2] + 1);
        }
        std::swap(before, previous);
        std::swap(previous, current);
    }
    return previous[y.size()];
}

std::vector<std::string> group_names(const Profile& profile) {
    std::vector<std::string> groups;
    for (const Parameter& parameter : profile.parameters) {
        if (!parameter.group.empty() && std::find(groups.begin(), groups.end(), parameter.group) == groups.end()) {
            groups.push_back(parameter.group);
        }
    }
    return groups;
}

std::vector<std::string> nearest_names(const Profile& profile, std::string_view typed_text, std::size_t most) {
    const std::string typed = folded_name(typed_text);
    if (typed.empty() || most == 0) return {};
    const std::size_t close = std::clamp<std::size_t>(typed.size() / 3, 1, 3);
    auto candidates = candidates_of(profile, typed);
    std::size_t best = std::string::npos;
    for (const auto& candidate : candidates) best = std::min(best, candidate.distance);
    if (best <= close) {
        // The nearest, and those one edit further while still close: "sett_point" offers
        // set_point, not set_point_2.
        const std::size_t farthest = std::min(best + 1, close);
        std::erase_if(candidates, [&](const Candidate& c) { return c.distance > farthest; });
        std::stable_sort(candidates.begin(), candidates.end(),
                         [](const Candidate& a, const Candidate& b) { return a.distance < b.distance; });
    } else {
        std::erase_if(candidates, [](const Candidate& c) { return !c.contains; });
    }
    std::vector<std::string> names;
    for (const auto& candidate : candidates) {
        if (names.size() == most) break;
        if (std::find(names.begin(), names.end(), candidate.label) == names.end()) names.push_back(candidate.label);
    }
    return names;
}

}  // namespace loopwire::device
