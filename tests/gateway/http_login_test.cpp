// The users file, password and token hashes, sessions, CSRF and the login limiter
// (gateway/http_users.hpp, gateway/http_sessions.hpp), in virtual time.
#include <gtest/gtest.h>

#include "gateway/http_sessions.hpp"
#include "gateway/http_users.hpp"
#include "profile/profile_registry.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;

struct VirtualClock {
    std::chrono::steady_clock::time_point now{std::chrono::hours(1000)};
    SteadyClock clock() {
        return [this] { return now; };
    }
};

const std::string token_line_hash = machine_token_hash("a-machine-token");

TEST(UsersFile, ReadsUsersAndSkipsCommentsAndBlankLines) {
    const std::string text = "# users\n\nada:admin:" + token_line_hash + "\r\nbob:viewer:$argon2id$v=19$m=65536,t=2,p=1$c2FsdA$aGFzaA\n";
    auto users = parse_users(text, "users");
    ASSERT_TRUE(users) << users.error().message;
    ASSERT_EQ(users->size(), 2u);
    EXPECT_EQ((*users)[0].name, "ada");
    EXPECT_EQ((*users)[0].role, Role::admin);
    EXPECT_TRUE((*users)[0].machine());
    EXPECT_EQ((*users)[1].role, Role::viewer);
    EXPECT_FALSE((*users)[1].machine());
}

TEST(UsersFile, NamesFileAndLineOfWhatIsWrong) {
    const auto message = [](const std::string& text) {
        auto users = parse_users(text, "/etc/users");
        return users ? std::string("accepted") : users.error().message;
    };
    EXPECT_EQ(message("# c\nada admin\n").rfind("/etc/users:2: expected NAME:ROLE:HASH", 0), 0u) << message("# c\nada admin\n");
    EXPECT_NE(message("ada:root:" + token_line_hash).find("/etc/users:1: \"root\" is not a role"), std::string::npos);
    EXPECT_NE(message("ada:admin:secret").find("/etc/users:1: the hash of \"ada\" is neither"), std::string::npos);
    EXPECT_NE(message("a da:admin:" + token_line_hash).find("is not a user name"), std::string::npos);
    EXPECT_NE(message("ada:admin:" + token_line_hash + "\nada:viewer:" + token_line_hash).find("/etc/users:2: the user \"ada\" has a line already"),
              std::string::npos);
    EXPECT_NE(message("ada:admin:token-sha256:12").find("neither"), std::string::npos);
}

TEST(UsersFile, RewritesTheUsersLineAndKeepsTheRest) {
    const std::string before = "# who\nada:admin:" + token_line_hash + "\nbob:viewer:" + token_line_hash + "\n";
    const std::string other = machine_token_hash("another");
    EXPECT_EQ(users_text_with(before, {"bob", Role::operator_, other}),
              "# who\nada:admin:" + token_line_hash + "\nbob:operator:" + other + "\n");
    EXPECT_EQ(users_text_with(before, {"cy", Role::viewer, other}), before + "cy:viewer:" + other + "\n");
    EXPECT_EQ(users_text_with("", {"cy", Role::viewer, other}), "cy:viewer:" + other + "\n");
}

TEST(Passwords, HashVerifiesItsPasswordAloneAndReadsBackFromTheFile) {
    auto hash = hash_password("correct horse");
    ASSERT_TRUE(hash) << hash.error().message;
    EXPECT_TRUE(hash->starts_with("$argon2id$"));
    EXPECT_TRUE(verify_password("correct horse", *hash));
    EXPECT_FALSE(verify_password("correct horsE", *hash));
    EXPECT_FALSE(verify_password("correct horse", token_line_hash));
    auto users = parse_users("ada:operator:" + *hash + "\n", "users");
    ASSERT_TRUE(users) << users.error().message;
    EXPECT_TRUE(verify_password("correct horse", users->front().hash));
    EXPECT_NE(*hash_password("correct horse"), *hash);  // salted
}

TEST(Passwords, MachineTokensAreRandomAndHashedBySha256) {
    const std::string token = new_machine_token();
    EXPECT_EQ(token.size(), 43u);
    EXPECT_NE(new_machine_token(), token);
    // SHA-256 of "abc" (FIPS 180-2, appendix B.1).
    EXPECT_EQ(machine_token_hash("abc"), "token-sha256:ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST(Roles, OperatorWritesTheProfilesAliasedValuesAdminEverything) {
    auto registry = device::ProfileRegistry::builtins();
    ASSERT_TRUE(registry);
    auto found = registry->find("tc10");
    ASSERT_TRUE(found);
    const device::Profile* tc10 = found->get();
    const auto parameter = [&](const std::string& name) -> const device::Parameter& {
        for (const auto& p : tc10->parameters) {
            if (p.name == name) return p;
        }
        ADD_FAILURE() << name;
        return tc10->parameters.front();
    };
    EXPECT_EQ(role_to_write(*tc10, parameter("set_point")), Role::operator_);
    EXPECT_TRUE(role_may_write(Role::operator_, *tc10, parameter("set_point")));
    EXPECT_FALSE(role_may_write(Role::viewer, *tc10, parameter("set_point")));
    EXPECT_EQ(role_to_write(*tc10, parameter("load_defaults")), Role::admin);
    EXPECT_FALSE(role_may_write(Role::operator_, *tc10, parameter("load_defaults")));
    EXPECT_TRUE(role_may_write(Role::admin, *tc10, parameter("load_defaults")));
}

TEST(Sessions, IdleTimeoutEndsASessionAndUseKeepsItOpen) {
    VirtualClock time;
    SessionStore store(8h, time.clock());
    const Session session = store.open("ada", Role::operator_);
    EXPECT_EQ(session.id.size(), 43u);
    EXPECT_NE(session.id, session.csrf);
    time.now += 7h;
    auto found = store.find(session.id);
    ASSERT_TRUE(found);
    EXPECT_EQ(found->user, "ada");
    EXPECT_EQ(found->csrf, session.csrf);
    time.now += 7h;  // 14 h after the login, 7 h after its last use
    EXPECT_TRUE(store.find(session.id));
    time.now += 8h;
    EXPECT_FALSE(store.find(session.id));
    EXPECT_EQ(store.size(), 0u);
}

TEST(Sessions, CloseAndReloadEndSessions) {
    SessionStore store(8h);
    const Session ada = store.open("ada", Role::operator_);
    const Session bob = store.open("bob", Role::viewer);
    const Session cy = store.open("cy", Role::admin);
    store.close(ada.id);
    EXPECT_FALSE(store.find(ada.id));
    store.keep_only({{"bob", Role::operator_, token_line_hash}, {"cy", Role::admin, token_line_hash}});
    EXPECT_FALSE(store.find(bob.id));  // its role changed
    EXPECT_TRUE(store.find(cy.id));
    EXPECT_FALSE(store.find("not-a-session"));
}

TEST(Sessions, AtTheLimitTheLeastRecentlyUsedGoes) {
    VirtualClock time;
    SessionStore store(8h, time.clock(), 2);
    const Session first = store.open("a", Role::viewer);
    time.now += 1s;
    const Session second = store.open("b", Role::viewer);
    time.now += 1s;
    store.find(first.id);
    time.now += 1s;
    const Session third = store.open("c", Role::viewer);
    EXPECT_TRUE(store.find(first.id));
    EXPECT_FALSE(store.find(second.id));
    EXPECT_TRUE(store.find(third.id));
}

TEST(Csrf, OnlyTheExactTokenMatches) {
    SessionStore store(8h);
    const Session session = store.open("ada", Role::operator_);
    EXPECT_TRUE(same_secret(session.csrf, session.csrf));
    EXPECT_FALSE(same_secret("", session.csrf));
    EXPECT_FALSE(same_secret(session.csrf.substr(1), session.csrf));
    std::string changed = session.csrf;
    changed.back() = changed.back() == 'A' ? 'B' : 'A';
    EXPECT_FALSE(same_secret(changed, session.csrf));
    EXPECT_FALSE(same_secret("", ""));
}

TEST(LoginLimiter, FiveFailuresAreFreeThenEachWaitsTwiceAsLong) {
    VirtualClock time;
    LoginLimiter limiter({}, time.clock());
    for (int i = 0; i < 4; ++i) {
        EXPECT_FALSE(limiter.failed("192.0.2.1")) << i;
        EXPECT_FALSE(limiter.wait_for("192.0.2.1"));
    }
    EXPECT_EQ(limiter.failed("192.0.2.1"), 1s);
    EXPECT_EQ(limiter.wait_for("192.0.2.1"), 1s);
    EXPECT_FALSE(limiter.wait_for("192.0.2.2"));  // another address is not held up
    time.now += 1s;
    EXPECT_FALSE(limiter.wait_for("192.0.2.1"));
    EXPECT_EQ(limiter.failed("192.0.2.1"), 2s);
    time.now += 500ms;
    EXPECT_EQ(limiter.wait_for("192.0.2.1"), 2s);  // 1.5 s, rounded up
    time.now += 1500ms;
    EXPECT_EQ(limiter.failed("192.0.2.1"), 4s);
    for (int i = 0; i < 20; ++i) limiter.failed("192.0.2.1");
    EXPECT_EQ(limiter.wait_for("192.0.2.1"), 300s);  // at most
    limiter.succeeded("192.0.2.1");
    EXPECT_FALSE(limiter.wait_for("192.0.2.1"));
    EXPECT_FALSE(limiter.failed("192.0.2.1"));
}

TEST(LoginLimiter, KeepsAtMostItsAddresses) {
    VirtualClock time;
    LoginLimiter limiter({5, 1s, 300s, 2}, time.clock());
    for (int i = 0; i < 5; ++i) limiter.failed("a");
    time.now += 1ms;
    limiter.failed("b");
    time.now += 1ms;
    limiter.failed("c");  // "a", the quietest, is forgotten
    EXPECT_FALSE(limiter.wait_for("a"));
}

TEST(LoginBody, JsonAndFormBothRead) {
    auto json = parse_login_body(R"({"user": "ada", "password": "p\u00e4ss"})", "application/json; charset=utf-8");
    ASSERT_TRUE(json);
    EXPECT_EQ(json->user, "ada");
    EXPECT_EQ(json->password, "p\xc3\xa4ss");
    auto form = parse_login_body("user=ada&password=a+b%26c", "application/x-www-form-urlencoded");
    ASSERT_TRUE(form);
    EXPECT_EQ(form->password, "a b&c");
    EXPECT_TRUE(parse_login_body(R"({"user":"ada","password":""})", ""));
    EXPECT_FALSE(parse_login_body(R"({"user":"ada"})", "application/json"));
    EXPECT_FALSE(parse_login_body(R"({"user":1,"password":"x"})", "application/json"));
    EXPECT_FALSE(parse_login_body("user=ada&password=x", "text/plain"));
    EXPECT_FALSE(parse_login_body("{not json", "application/json"));
    EXPECT_FALSE(parse_login_body("password=x", ""));
}

TEST(CookieHeader, FindsTheNamedCookie) {
    EXPECT_EQ(cookie_value("a=1; loopwire_session=XYZ; b=2", "loopwire_session"), "XYZ");
    EXPECT_EQ(cookie_value("loopwire_session=\"Q\"", "loopwire_session"), "Q");
    EXPECT_EQ(cookie_value("xloopwire_session=1", "loopwire_session"), std::nullopt);
    EXPECT_EQ(cookie_value("", "loopwire_session"), std::nullopt);
    EXPECT_EQ(cookie_value(";;=;loopwire_session", "loopwire_session"), std::nullopt);
}

}  // namespace
}  // namespace loopwire::gateway
