#pragma once
// The master side of a link as the CLI and other users of the client layer meet it: the master,
// its frame trace, and opening the link a URL names. The CLI (app/) reaches sessions and
// transports only through here (docs/DESIGN.md, "Layers").
#include <memory>
#include <string>

#include "common/result.hpp"
#include "session/master.hpp"
#include "session/trace.hpp"

namespace loopwire::device {

using session::Master;
using session::MasterOptions;
using session::TraceDirection;
using session::TraceEvent;
using session::TraceSink;

// Opens the link `url` names (rtu:..., ascii:..., linking:..., tcp://..., rtu+tcp://...) and
// the master that speaks its framing; a malformed URL is a usage error.
Result<std::unique_ptr<Master>> open_link(const std::string& url, MasterOptions options);

// The usage error of a malformed URL, found without opening anything.
Result<void> check_link_url(const std::string& url);

// Whether `url` names a Linking link, which carries one register per message; a malformed URL
// is a usage error.
Result<bool> is_linking_link(const std::string& url);

}  // namespace loopwire::device
