#pragma once
// The people and machines the HTTP API knows ([http] users_file), and what each may do.
//
// The users file holds one line a user, `NAME:ROLE:HASH`; blank lines and lines starting with
// '#' are left alone. HASH is either a password's Argon2id hash as libsodium writes it
// (crypto_pwhash_str: "$argon2id$v=19$m=...,t=...,p=...$SALT$HASH"), for a person who logs in,
// or "token-sha256:HEX", the SHA-256 of a machine's bearer token: a token is 32 random bytes,
// so a fast hash is as strong as a slow one, and checking one costs nothing per request.
// `loopwire passwd` writes both kinds.
//
// Roles, each allowing what the one before does and more:
//   viewer    reads
//   operator  writes the set points and modes: the writable parameters the device's profile
//             names by an alias (SP, OUT, MODE: the values the dashboard shows first)
//   admin     writes every writable parameter (configuration included)
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/result.hpp"

namespace loopwire::device {
struct Profile;
struct Parameter;
}  // namespace loopwire::device

namespace loopwire::gateway {

enum class Role { viewer, operator_, admin };

std::string_view role_name(Role role);
std::optional<Role> parse_role(std::string_view name);

struct HttpUser {
    std::string name;
    Role role = Role::viewer;
    std::string hash;  // "$argon2id$..." or "token-sha256:HEX"
    bool machine() const;
    bool operator==(const HttpUser&) const = default;
};

// The lines of a users file. An error names "FILE:LINE" and what is wrong: a line not
// NAME:ROLE:HASH, a name used twice or not [A-Za-z0-9._@-]{1,64}, an unknown role, a hash
// that is neither kind. `file` is only for the messages.
Result<std::vector<HttpUser>> parse_users(std::string_view text, const std::string& file);

// The text of a users file: `existing` with `user`'s line replaced (the first of that name),
// or added at the end; comments and blank lines kept.
std::string users_text_with(std::string_view existing, const HttpUser& user);

// A password's Argon2id hash (libsodium's interactive limits: 2 passes over 64 MiB), or why
// not (out of memory). Slow on purpose: 0.34 s measured on a busy 2-core machine.
Result<std::string> hash_password(std::string_view password);
// Whether `password` is the one `hash` was made from; as slow as hash_password.
bool verify_password(std::string_view password, const std::string& hash);

// 32 random bytes, base64url without padding (43 characters): session ids, CSRF tokens.
std::string random_secret();
// A new machine token: a random_secret().
std::string new_machine_token();
// The users-file hash of a machine token: "token-sha256:" and the SHA-256 in hex.
std::string machine_token_hash(std::string_view token);

// Whether `role` may write `parameter` of a device of `profile` (see the roles above).
bool role_may_write(Role role, const device::Profile& profile, const device::Parameter& parameter);
// The role a write of `parameter` needs.
Role role_to_write(const device::Profile& profile, const device::Parameter& parameter);

// libsodium's start-up, once per process (idempotent, thread-safe); false when it cannot start.
bool start_sodium();

}  // namespace loopwire::gateway
