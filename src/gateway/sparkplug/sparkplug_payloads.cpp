#include "gateway/sparkplug/sparkplug_payloads.hpp"

#include <charconv>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "client/device_status.hpp"
#include "common/peer_text.hpp"

#include "sparkplug/sparkplug_b.pb.h"  // generated from sparkplug_b.proto

namespace loopwire::gateway::sparkplug {
namespace {

using Payload = loopwire::sparkplug::b::Payload;

// Signed datatypes whose values travel in int_value / long_value as two's complement (6.4.10).
constexpr std::uint32_t int8_code = 1;
constexpr std::uint32_t int64_code = 4;

bool fixed_whole(const device::Parameter& parameter) {
    const int* decimals = std::get_if<int>(&parameter.decimals);
    return decimals && *decimals == 0;
}

// A number to the metric's datatype: whole datatypes take the nearest whole number.
MetricValue number_value(DataType type, double number) {
    switch (type) {
        case DataType::int16:
        case DataType::int32: return static_cast<std::int64_t>(std::llround(number));
        case DataType::uint16:
        case DataType::uint64: return static_cast<std::uint64_t>(std::llround(std::max(number, 0.0)));
        case DataType::boolean: return number != 0.0;
        default: return number;
    }
}

// A labelled bit (a Boolean parameter's "on"/"off") as true or false: true is the label of 1.
bool label_is_set(const device::Parameter& parameter, const std::string& label) {
    const auto one = parameter.enum_labels.find(1);
    return one != parameter.enum_labels.end() && one->second == label;
}

MetricValue value_of(const MetricDefinition& metric, const ValueChange& change) {
    const device::Parameter& parameter = *metric.parameter;
    const auto& value = change.value->value;
    if (!metric.bit.empty()) {
        const auto* bits = std::get_if<std::map<std::string, bool>>(&value);
        if (!bits) return std::monostate{};
        const auto bit = bits->find(metric.bit);
        return bit == bits->end() ? MetricValue{} : MetricValue{bit->second};
    }
    if (parameter.type == device::ValueType::bitfield) return static_cast<std::uint64_t>(change.value->raw);
    if (metric.type == DataType::string) return change.text;
    if (const auto* number = std::get_if<double>(&value)) return number_value(metric.type, *number);
    if (const auto* label = std::get_if<std::string>(&value)) {
        if (metric.type == DataType::boolean) return label_is_set(parameter, *label);
    }
    return std::monostate{};
}

void set_value(Payload::Metric& out, const MetricValue& value, DataType type) {
    std::visit(
        [&](const auto& v) {
            using V = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<V, std::monostate>) {
                out.set_is_null(true);
            } else if constexpr (std::is_same_v<V, std::int64_t>) {
                // Int8..Int32 in int_value, two's complement in 32 bits; Int64 in long_value.
                if (type == DataType::int16 || type == DataType::int32) {
                    out.set_int_value(static_cast<std::uint32_t>(static_cast<std::int32_t>(v)));
                } else {
                    out.set_long_value(static_cast<std::uint64_t>(v));
                }
            } else if constexpr (std::is_same_v<V, std::uint64_t>) {
                if (type == DataType::uint16) {
                    out.set_int_value(static_cast<std::uint32_t>(v));
                } else {
                    out.set_long_value(v);
                }
            } else if constexpr (std::is_same_v<V, double>) {
                out.set_double_value(v);
            } else if constexpr (std::is_same_v<V, bool>) {
                out.set_boolean_value(v);
            } else {
                out.set_string_value(v);
            }
        },
        value);
}

void add_property(Payload::PropertySet& set, const std::string& key, DataType type, const MetricValue& value) {
    set.add_keys(key);
    Payload::PropertyValue& property = *set.add_values();
    property.set_type(static_cast<std::uint32_t>(type));
    std::visit(
        [&](const auto& v) {
            using V = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<V, std::monostate>) {
                property.set_is_null(true);
            } else if constexpr (std::is_same_v<V, std::int64_t>) {
                property.set_int_value(static_cast<std::uint32_t>(static_cast<std::int32_t>(v)));
            } else if constexpr (std::is_same_v<V, std::uint64_t>) {
                property.set_long_value(v);
            } else if constexpr (std::is_same_v<V, double>) {
                property.set_double_value(v);
            } else if constexpr (std::is_same_v<V, bool>) {
                property.set_boolean_value(v);
            } else {
                property.set_string_value(v);
            }
        },
        value);
}

void add_quality(Payload::Metric& out, std::int32_t quality) {
    add_property(*out.mutable_properties(), "Quality", DataType::int32, static_cast<std::int64_t>(quality));
}

// A Float as the decimal its sender meant: the shortest text that reads back as the same 32-bit
// value, taken as a double. Widened as it is, 12.3 sent as a Float is 12.300000190734863, a value
// finer than any parameter's decimals; the sender's 12.3 is the one decimal within half a Float's
// step of it. A value truly finer (12.34 for a parameter of one decimal) keeps its digits, and
// the write refuses it for them.
double float_as_meant(float value) {
    if (!std::isfinite(value)) return static_cast<double>(value);
    const std::string text = fmt::format("{}", value);
    double meant = 0;
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), meant);
    return error == std::errc() && end == text.data() + text.size() ? meant : static_cast<double>(value);
}

MetricValue command_value(const Payload::Metric& metric) {
    const std::uint32_t type = metric.datatype();
    switch (metric.value_case()) {
        case Payload::Metric::kIntValue:
            if (type >= int8_code && type < int64_code) return static_cast<std::int64_t>(static_cast<std::int32_t>(metric.int_value()));
            return static_cast<std::uint64_t>(metric.int_value());
        case Payload::Metric::kLongValue:
            if (type == int64_code) return static_cast<std::int64_t>(metric.long_value());
            return metric.long_value();
        case Payload::Metric::kFloatValue: return float_as_meant(metric.float_value());
        case Payload::Metric::kDoubleValue: return metric.double_value();
        case Payload::Metric::kBooleanValue: return metric.boolean_value();
        case Payload::Metric::kStringValue: return metric.string_value();
        default: return std::monostate{};
    }
}

}  // namespace

DataType datatype_of(const device::Parameter& parameter) {
    switch (parameter.type) {
        case device::ValueType::boolean: return DataType::boolean;
        case device::ValueType::enumeration: return DataType::string;
        case device::ValueType::bitfield: return DataType::uint16;
        case device::ValueType::int16:
        case device::ValueType::uint16: break;
    }
    // A number some of whose words are labels ("off", "----") is sent as its text.
    if (!parameter.enum_labels.empty()) return DataType::string;
    if (!fixed_whole(parameter)) return DataType::float64;
    return parameter.type == device::ValueType::int16 ? DataType::int16 : DataType::uint16;
}

std::vector<MetricDefinition> parameter_metrics(const device::Parameter& parameter, std::uint64_t& next_alias) {
    const std::string name = parameter.group.empty() ? parameter.name : parameter.group + "/" + parameter.name;
    std::vector<MetricDefinition> metrics{{name, next_alias++, datatype_of(parameter), &parameter, {}}};
    if (parameter.type == device::ValueType::bitfield) {
        for (const auto& [bit, bit_name] : parameter.bit_names) {
            metrics.push_back({name + "/" + bit_name, next_alias++, DataType::boolean, &parameter, bit_name});
        }
    }
    return metrics;
}

MetricSample sample_of(const MetricDefinition& metric, const ValueChange& change) {
    MetricSample sample;
    sample.timestamp = static_cast<std::uint64_t>(
        std::chrono::duration_cast<std::chrono::milliseconds>(change.sampled.time_since_epoch()).count());
    if (change.status == device::status_text(device::DeviceStatus::stale)) {
        sample.quality = quality_stale;
    } else if (!change.value || !metric.parameter) {
        sample.quality = quality_bad;
    } else {
        sample.value = value_of(metric, change);
        if (std::holds_alternative<std::monostate>(sample.value)) sample.quality = quality_bad;  // a special state
    }
    return sample;
}

MetricProperties properties_of(const MetricDefinition& metric, const ValueChange* latest, bool writes_on) {
    MetricProperties properties;
    if (!metric.parameter) return properties;
    const device::Parameter& parameter = *metric.parameter;
    properties.mnemonic = parameter.mnemonic;
    properties.documentation = parameter.description;
    if (!metric.bit.empty()) return properties;  // a bit: read-only, no unit
    properties.writable = writes_on && parameter.writable;
    if (metric.type == DataType::boolean || metric.type == DataType::string || parameter.type == device::ValueType::bitfield) {
        return properties;
    }
    if (latest) properties.unit = latest->unit;
    if (properties.unit == device::unknown_unit) properties.unit.clear();
    if (const int* fixed = std::get_if<int>(&parameter.decimals)) {
        properties.decimals = *fixed;
    } else if (latest && latest->value && std::holds_alternative<double>(latest->value->value)) {
        properties.decimals = latest->decimals;
    }
    // The limits every front shows (device::ResolvedValue::limits: as the device holds them, a
    // set point's SP.LL and SP.HL); before a value, those nothing read is needed for. A change is
    // a new birth.
    const device::ValueLimits known = latest ? latest->limits : device::limits_of(parameter, {});
    properties.low = known.min;
    properties.high = known.max;
    return properties;
}

struct PayloadWriter::Message {
    Payload payload;
};

PayloadWriter::PayloadWriter(std::uint64_t timestamp, std::optional<std::uint64_t> seq) : message_(std::make_unique<Message>()) {
    message_->payload.set_timestamp(timestamp);
    if (seq) message_->payload.set_seq(*seq);
}

PayloadWriter::~PayloadWriter() = default;

void PayloadWriter::birth_metric(const MetricDefinition& metric, const MetricSample& sample, const MetricProperties* properties) {
    Payload::Metric& out = *message_->payload.add_metrics();
    out.set_name(metric.name);
    out.set_alias(metric.alias);
    out.set_datatype(static_cast<std::uint32_t>(metric.type));
    out.set_timestamp(sample.timestamp);
    set_value(out, sample.value, metric.type);
    if (!properties) return;
    add_quality(out, sample.quality);
    Payload::PropertySet& set = *out.mutable_properties();
    if (!properties->unit.empty()) add_property(set, "engUnit", DataType::string, properties->unit);
    if (properties->low) add_property(set, "engLow", DataType::float64, *properties->low);
    if (properties->high) add_property(set, "engHigh", DataType::float64, *properties->high);
    if (properties->decimals) add_property(set, "decimals", DataType::int32, static_cast<std::int64_t>(*properties->decimals));
    add_property(set, "writable", DataType::boolean, properties->writable);
    add_property(set, "readOnly", DataType::boolean, !properties->writable);
    if (!properties->mnemonic.empty()) add_property(set, "mnemonic", DataType::string, properties->mnemonic);
    if (!properties->documentation.empty()) add_property(set, "documentation", DataType::string, properties->documentation);
}

void PayloadWriter::data_metric(const MetricDefinition& metric, const MetricSample& sample, bool with_quality, bool historical) {
    Payload::Metric& out = *message_->payload.add_metrics();
    out.set_alias(metric.alias);
    out.set_timestamp(sample.timestamp);
    if (historical) out.set_is_historical(true);
    set_value(out, sample.value, metric.type);
    if (with_quality) add_quality(out, sample.quality);
}

std::string PayloadWriter::bytes() const { return message_->payload.SerializeAsString(); }

Result<std::vector<CommandMetric>> decode_command(std::string_view bytes) {
    Payload payload;
    if (bytes.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()) ||
        !payload.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
        return make_error(ErrorKind::usage, fmt::format("not a Sparkplug B payload ({} bytes that protobuf cannot decode)", bytes.size()));
    }
    std::vector<CommandMetric> metrics;
    for (const auto& metric : payload.metrics()) {
        CommandMetric command;
        command.name = metric.name();
        if (metric.has_alias()) command.alias = metric.alias();
        command.value = metric.is_null() ? MetricValue{} : command_value(metric);
        metrics.push_back(std::move(command));
    }
    return metrics;
}

std::string value_words(const MetricValue& value) {
    return std::visit(
        [](const auto& v) -> std::string {
            using V = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<V, std::monostate>) {
                return "null";
            } else if constexpr (std::is_same_v<V, bool>) {
                return v ? "true" : "false";
            } else if constexpr (std::is_same_v<V, std::string>) {
                return quoted_excerpt(v);  // a peer's text: escaped and cut for a log line
            } else {
                return fmt::format("{}", v);
            }
        },
        value);
}

Result<std::string> write_text(const MetricDefinition& metric, const MetricValue& value) {
    const auto refuse = [&](std::string why) {
        return make_error(ErrorKind::usage, fmt::format("{} = {}: {}", metric.name, value_words(value), why));
    };
    if (!metric.parameter) return refuse("not a device parameter; nothing to write");
    if (!metric.bit.empty()) return refuse("a bit of a bit field; write the whole word");
    const device::Parameter& parameter = *metric.parameter;
    if (std::holds_alternative<std::monostate>(value)) return refuse("no value given");
    if (const auto* text = std::get_if<std::string>(&value)) return *text;  // a label, or a number as text
    if (const auto* flag = std::get_if<bool>(&value)) {
        if (metric.type != DataType::boolean) return refuse(fmt::format("a Boolean, but the metric is a {}", static_cast<unsigned>(metric.type)));
        const auto label = parameter.enum_labels.find(*flag ? 1 : 0);
        return label != parameter.enum_labels.end() ? label->second : std::string(*flag ? "1" : "0");
    }
    if (const auto* number = std::get_if<double>(&value)) {
        if (!std::isfinite(*number)) return refuse("not a finite number");
        return fmt::format("{}", *number);
    }
    if (const auto* whole = std::get_if<std::int64_t>(&value)) return std::to_string(*whole);
    return std::to_string(std::get<std::uint64_t>(value));
}

}  // namespace loopwire::gateway::sparkplug
