#pragma once
// Commands run with --json also print their errors as JSON on stdout, so a script reading stdout
// always gets a JSON document: {"error": MESSAGE, "kind": KIND} (kinds: usage, link, timeout,
// exception, malformed, mismatch), with "code" and "exception" (its name) for a Modbus exception.
// The message also goes to stderr as for any command.
#include <nlohmann/json.hpp>

#include "common/result.hpp"

namespace loopwire::app {

nlohmann::ordered_json error_json(const Error& error);

// While one lives, report_error (command_line.hpp) prints error_json on stdout as well; `on`
// false turns that off for a scope (an error already carried by the JSON printed).
class JsonErrors {
public:
    explicit JsonErrors(bool on);
    ~JsonErrors();
    JsonErrors(const JsonErrors&) = delete;
    JsonErrors& operator=(const JsonErrors&) = delete;

private:
    bool previous_;
};

bool json_errors_on();

}  // namespace loopwire::app
