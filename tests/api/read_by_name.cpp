// The library as a program: reads parameters by name through the public API and prints each
// reading as one JSON line, so tests/gateway/cross_front_check.py can set the library's view
// beside the other fronts'.
//   read_by_name LINK DEVICE@UNIT NAME...
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <loopwire/loopwire.hpp>

namespace {

std::string quoted(const std::string& text) {
    std::string out = "\"";
    for (const char c : text) {
        if (c == '"' || c == '\\') out += '\\';
        if (static_cast<unsigned char>(c) < 0x20) {
            char escaped[8];
            std::snprintf(escaped, sizeof escaped, "\\u%04x", static_cast<unsigned>(c));
            out += escaped;
            continue;
        }
        out += c;
    }
    return out + '"';
}

std::string number(const std::optional<double>& value) {
    if (!value) return "null";
    char text[32];
    std::snprintf(text, sizeof text, "%.17g", *value);
    return text;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 4) {
        std::cerr << "usage: read_by_name LINK DEVICE@UNIT NAME...\n";
        return 2;
    }
    try {
        loopwire::Link link = loopwire::Link::open(argv[1]);
        loopwire::Device device(link, argv[2]);
        const auto readings = device.read(std::vector<std::string>(argv + 3, argv + argc));
        for (const auto& r : readings) {
            std::cout << "{\"name\":" << quoted(r.name) << ",\"text\":" << quoted(r.text) << ",\"unit\":" << quoted(r.unit)
                      << ",\"min\":" << number(r.min) << ",\"max\":" << number(r.max) << ",\"status\":" << quoted(r.status)
                      << ",\"error\":" << quoted(r.error) << "}\n";
        }
    } catch (const loopwire::Failure& failure) {
        std::cerr << "read_by_name: " << failure.what() << '\n';
        return 1;
    }
    return 0;
}
