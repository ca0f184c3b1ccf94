#include "client/link.hpp"

#include "transport/link_url.hpp"

namespace loopwire::device {

Result<std::unique_ptr<Master>> open_link(const std::string& url, MasterOptions options) {
    auto parsed = transport::parse_link_url(url);
    if (!parsed) return parsed.error();
    return session::open_master(*parsed, std::move(options));
}

Result<void> check_link_url(const std::string& url) {
    if (auto parsed = transport::parse_link_url(url); !parsed) return parsed.error();
    return {};
}

Result<bool> is_linking_link(const std::string& url) {
    auto parsed = transport::parse_link_url(url);
    if (!parsed) return parsed.error();
    return parsed->framing == transport::Framing::linking;
}

}  // namespace loopwire::device
