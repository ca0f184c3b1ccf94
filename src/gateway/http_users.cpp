#include "gateway/http_users.hpp"

#include <algorithm>
#include <array>
#include <set>

#include <fmt/format.h>
#include <sodium.h>

#include "common/peer_text.hpp"
#include "profile/profile.hpp"

namespace loopwire::gateway {
namespace {

constexpr std::string_view token_prefix = "token-sha256:";
constexpr std::string_view argon2id_prefix = "$argon2id$";

bool valid_name(std::string_view name) {
    return !name.empty() && name.size() <= 64 && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
               c == '@' || c == '-';
    });
}

bool valid_hash(std::string_view hash) {
    if (hash.starts_with(token_prefix)) {
        const auto hex = hash.substr(token_prefix.size());
        return hex.size() == 64 && std::all_of(hex.begin(), hex.end(), [](char c) {
                   return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
               });
    }
    // libsodium's own string: its fields are checked when a password is verified against it.
    return hash.starts_with(argon2id_prefix) && hash.size() < crypto_pwhash_STRBYTES &&
           std::none_of(hash.begin(), hash.end(), [](char c) { return c <= ' ' || c == ':' || c == 0x7f; });
}

// A line without its end; comments and blank lines are not users.
bool is_user_line(std::string_view line) {
    const auto first = line.find_first_not_of(" \t\r");
    return first != std::string_view::npos && line[first] != '#';
}

std::vector<std::string_view> lines_of(std::string_view text) {
    std::vector<std::string_view> lines;
    while (!text.empty()) {
        const auto end = text.find('\n');
        std::string_view line = text.substr(0, end);
        if (line.ends_with('\r')) line.remove_suffix(1);
        lines.push_back(line);
        if (end == std::string_view::npos) break;
        text.remove_prefix(end + 1);
    }
    return lines;
}

}  // namespace

std::string_view role_name(Role role) {
    switch (role) {
        case Role::viewer: return "viewer";
        case Role::operator_: return "operator";
        case Role::admin: return "admin";
    }
    return "viewer";
}

std::optional<Role> parse_role(std::string_view name) {
    for (const Role role : {Role::viewer, Role::operator_, Role::admin}) {
        if (role_name(role) == name) return role;
    }
    return std::nullopt;
}

bool HttpUser::machine() const { return hash.starts_with(token_prefix); }

Result<std::vector<HttpUser>> parse_users(std::string_view text, const std::string& file) {
    std::vector<HttpUser> users;
    std::set<std::string, std::less<>> names;
    const auto lines = lines_of(text);
    for (std::size_t i = 0; i < lines.size(); ++i) {
        const std::string_view line = lines[i];
        if (!is_user_line(line)) continue;
        const auto fail = [&](const std::string& what) {
            return make_error(ErrorKind::usage, fmt::format("{}:{}: {}", file, i + 1, what));
        };
        const auto first = line.find(':');
        const auto second = first == std::string_view::npos ? first : line.find(':', first + 1);
        if (second == std::string_view::npos) {
            return fail("expected NAME:ROLE:HASH (write the line with `loopwire passwd FILE NAME --role ROLE`)");
        }
        const std::string_view name = line.substr(0, first);
        const std::string_view role = line.substr(first + 1, second - first - 1);
        const std::string_view hash = line.substr(second + 1);
        if (!valid_name(name)) {
            return fail(fmt::format("{} is not a user name (1 to 64 of A-Z a-z 0-9 . _ @ -)", quoted_excerpt(name)));
        }
        if (names.count(name) != 0) return fail(fmt::format("the user \"{}\" has a line already", name));
        const auto known_role = parse_role(role);
        if (!known_role) {
            return fail(fmt::format("{} is not a role (viewer, operator or admin)", quoted_excerpt(role)));
        }
        if (!valid_hash(hash)) {
            return fail(fmt::format("the hash of \"{}\" is neither an Argon2id hash ($argon2id$...) nor a token's "
                                    "(token-sha256:HEX); write it again with `loopwire passwd`",
                                    name));
        }
        names.emplace(name);
        users.push_back({std::string(name), *known_role, std::string(hash)});
    }
    return users;
}

std::string users_text_with(std::string_view existing, const HttpUser& user) {
    const std::string line = fmt::format("{}:{}:{}", user.name, role_name(user.role), user.hash);
    std::string text;
    bool replaced = false;
    for (const std::string_view old : lines_of(existing)) {
        const bool same = !replaced && is_user_line(old) && old.substr(0, old.find(':')) == user.name;
        text += same ? line : std::string(old);
        text += '\n';
        replaced = replaced || same;
    }
    if (!replaced) text += line + '\n';
    return text;
}

bool start_sodium() { return ::sodium_init() >= 0; }

Result<std::string> hash_password(std::string_view password) {
    if (!start_sodium()) return make_error(ErrorKind::link, "libsodium cannot start (no source of random numbers?)");
    std::array<char, crypto_pwhash_STRBYTES> hash{};
    if (::crypto_pwhash_str_alg(hash.data(), password.data(), password.size(), crypto_pwhash_OPSLIMIT_INTERACTIVE,
                                crypto_pwhash_MEMLIMIT_INTERACTIVE, crypto_pwhash_ALG_ARGON2ID13) != 0) {
        return make_error(ErrorKind::link, "cannot hash the password: Argon2id needs 64 MiB of memory, which is not free");
    }
    return std::string(hash.data());
}

bool verify_password(std::string_view password, const std::string& hash) {
    if (!start_sodium() || !hash.starts_with(argon2id_prefix)) return false;
    return ::crypto_pwhash_str_verify(hash.c_str(), password.data(), password.size()) == 0;
}

std::string new_machine_token() { return random_secret(); }

std::string random_secret() {
    start_sodium();
    std::array<unsigned char, 32> bytes{};
    ::randombytes_buf(bytes.data(), bytes.size());
    std::array<char, sodium_base64_ENCODED_LEN(32, sodium_base64_VARIANT_URLSAFE_NO_PADDING)> text{};
    ::sodium_bin2base64(text.data(), text.size(), bytes.data(), bytes.size(), sodium_base64_VARIANT_URLSAFE_NO_PADDING);
    return std::string(text.data());
}

std::string machine_token_hash(std::string_view token) {
    start_sodium();
    std::array<unsigned char, crypto_hash_sha256_BYTES> digest{};
    ::crypto_hash_sha256(digest.data(), reinterpret_cast<const unsigned char*>(token.data()), token.size());
    std::array<char, crypto_hash_sha256_BYTES * 2 + 1> hex{};
    ::sodium_bin2hex(hex.data(), hex.size(), digest.data(), digest.size());
    return std::string(token_prefix) + hex.data();
}

Role role_to_write(const device::Profile& profile, const device::Parameter& parameter) {
    // The aliases (SP, OUT, MODE) are the profile's word for the values an operator works with;
    // every other writable word is the device's configuration.
    for (const auto& [alias, name] : profile.aliases) {
        if (name == parameter.name) return Role::operator_;
    }
    return Role::admin;
}

bool role_may_write(Role role, const device::Profile& profile, const device::Parameter& parameter) {
    return static_cast<int>(role) >= static_cast<int>(role_to_write(profile, parameter));
}

}  // namespace loopwire::gateway
