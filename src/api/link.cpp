#include <loopwire/link.hpp>

#include "api/failure_translation.hpp"
#include "api/link_state.hpp"
#include "transport/link_url.hpp"

namespace loopwire {

Link::Link(std::shared_ptr<State> state) : state_(std::move(state)) {}

Link Link::open(const std::string& url, const LinkOptions& options) {
    auto link = api::value_or_throw(transport::parse_link_url(url));
    if (link.is_serial() && link.path == "virtual") {
        throw Failure(Failure::Kind::usage, "'" + url + "': a virtual bus exists only inside the command line's own "
                                            "process; serve simulated devices on tcp://127.0.0.1:0 instead (loopwire::Simulator)");
    }
    session::MasterOptions master_options;
    master_options.timeout = options.timeout;
    master_options.retries = options.retries;
    auto master = api::value_or_throw(session::open_master(link, std::move(master_options)));
    return Link(std::make_shared<State>(State{std::move(master)}));
}

std::string Link::describe() const { return state_->master->describe(); }

}  // namespace loopwire
