// What a browser or a guesser sends to the HTTP API's logins (gateway/http_sessions.hpp): the
// login body (JSON or a form, under any Content-Type) and the Cookie header, on arbitrary bytes.
// The first byte picks the Content-Type; the rest, split at the first NUL, is the body and the
// Cookie header. Properties: nothing throws or aborts; a body that is read gives a user of 1..64
// bytes and a password of at most 1024; a cookie found is a substring of the header.
#include <array>
#include <string>
#include <string_view>

#include "fuzz_support.hpp"
#include "gateway/http_sessions.hpp"
#include "gateway/http_users.hpp"

using namespace loopwire;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    static constexpr std::array<std::string_view, 5> types = {
        "", "application/json", "application/x-www-form-urlencoded", "application/json; charset=utf-8", "text/plain"};
    const std::string_view type = types[data[0] % types.size()];
    const std::string_view rest(reinterpret_cast<const char*>(data + 1), size - 1);
    const auto nul = rest.find('\0');
    const std::string_view body = rest.substr(0, nul);
    const std::string_view cookie = nul == std::string_view::npos ? std::string_view() : rest.substr(nul + 1);

    if (const auto form = gateway::parse_login_body(body, type)) {
        fuzz::check(!form->user.empty() && form->user.size() <= 64, "a login's user is 1..64 bytes");
        fuzz::check(form->password.size() <= 1024, "a login's password is at most 1024 bytes");
    }
    if (const auto value = gateway::cookie_value(cookie, gateway::session_cookie)) {
        fuzz::check(cookie.find(*value) != std::string_view::npos, "a cookie's value is part of the header");
    }
    // The users file on the same bytes: a line-numbered error or users with valid roles.
    const auto users = gateway::parse_users(rest, "users");
    if (!users) fuzz::check(users.error().message.rfind("users:", 0) == 0, "a users file's error names its line");
    return 0;
}
