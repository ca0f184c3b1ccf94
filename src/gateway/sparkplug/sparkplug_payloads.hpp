#pragma once
// Sparkplug B metrics and payloads (Eclipse Sparkplug 3.0, chapter 6) for the gateway's edge
// node (sparkplug_node.hpp): the metrics a polled parameter becomes, the value and quality a
// poll gives each, the protobuf of births, data and deaths, and the metrics of a command with
// the text `loopwire write` takes for each. Pure functions, apart from the network code, so
// that they are tested alone; the protobuf types stay inside the .cpp.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "common/result.hpp"
#include "gateway/value_cache.hpp"
#include "profile/profile.hpp"

namespace loopwire::gateway::sparkplug {

// The datatype codes of the specification (6.4.16) that the gateway sends.
enum class DataType : std::uint32_t {
    int16 = 2,
    int32 = 3,
    uint16 = 6,
    uint64 = 8,
    float32 = 9,
    float64 = 10,  // "Double"
    boolean = 11,
    string = 12,
};

// The `Quality` property, in the codes Sparkplug host applications such as Ignition read: a
// value read from the device, one no longer known to be the device's (its poll is overdue), and
// none (no reply, a special state such as under-range). The last two go with `is_null`.
constexpr std::int32_t quality_good = 192;
constexpr std::int32_t quality_stale = 500;
constexpr std::int32_t quality_bad = 0;

// A metric's value; monostate is `is_null`.
using MetricValue = std::variant<std::monostate, std::int64_t, std::uint64_t, double, bool, std::string>;

struct MetricSample {
    MetricValue value;
    std::int32_t quality = quality_good;
    std::uint64_t timestamp = 0;  // ms since the Unix epoch, UTC: when the poll that read it started

    // Whether a host application would learn nothing from this after `other`.
    bool same_report(const MetricSample& other) const { return value == other.value && quality == other.quality; }
};

// What a birth says of a metric besides its value, under the property names Ignition reads
// (engUnit, engLow, engHigh, readOnly) where it has one.
struct MetricProperties {
    std::string unit;
    std::optional<double> low;
    std::optional<double> high;
    std::optional<int> decimals;
    bool writable = false;
    std::string mnemonic;       // the manual's code for it ("rV", "SP1")
    std::string documentation;  // the profile's description

    bool operator==(const MetricProperties&) const = default;
};

// A metric of the node or of a device, fixed at birth.
struct MetricDefinition {
    std::string name;  // "measured_value", "alarms/alarm_1": the profile's group before the name
    std::uint64_t alias = 0;
    DataType type = DataType::string;
    const device::Parameter* parameter = nullptr;  // none: the node's own, or Device Control/...
    std::string bit;  // a bit field's named bit: the metric is that bit's state
};

// The datatype a parameter's value is sent as: Int16 or UInt16 for a whole number (fixed
// decimals 0), Double for a scaled one (0.85 is not exact in a Float), Boolean for a bit, String
// for an enumeration's label (and for any word the profile labels), UInt16 for a bit field's word.
DataType datatype_of(const device::Parameter& parameter);

// The metrics one polled parameter becomes, numbered from `next_alias` on: its own, and for a
// bit field one Boolean per named bit ("status_word/heating").
std::vector<MetricDefinition> parameter_metrics(const device::Parameter& parameter, std::uint64_t& next_alias);

// The value and quality a change gives the metric. A value that is missing or stale is null
// with the quality saying which, never its old number.
MetricSample sample_of(const MetricDefinition& metric, const ValueChange& change);

// The birth properties of a parameter's metric; `latest` (may be null) gives the unit and the
// decimals the device's configuration resolved. Limits are the profile's fixed ones. Writable
// only when the profile lets the parameter be written and `writes_on` (the node takes DCMDs):
// a host application must not offer a write the node will refuse.
MetricProperties properties_of(const MetricDefinition& metric, const ValueChange* latest, bool writes_on);

// One payload being built. The node's messages all carry `seq` but NDEATH (6.4.18).
class PayloadWriter {
public:
    PayloadWriter(std::uint64_t timestamp, std::optional<std::uint64_t> seq);
    ~PayloadWriter();
    PayloadWriter(const PayloadWriter&) = delete;
    PayloadWriter& operator=(const PayloadWriter&) = delete;

    // In a birth: name, alias, datatype, timestamp, value and properties (when given). The
    // Quality property goes with every birth metric.
    void birth_metric(const MetricDefinition& metric, const MetricSample& sample, const MetricProperties* properties);
    // In data: the alias alone (6.4.10: a birth named it), timestamp and value; the Quality
    // property when `with_quality` (the node sends it when the quality is not good, or was not).
    // `historical`: a value of the past sent late (store and forward), which a host records
    // without taking it for the metric's current value.
    void data_metric(const MetricDefinition& metric, const MetricSample& sample, bool with_quality, bool historical = false);

    std::string bytes() const;

private:
    struct Message;
    std::unique_ptr<Message> message_;
};

// A metric of an NCMD or DCMD: named by name or alias (or both), with a value.
struct CommandMetric {
    std::string name;
    std::optional<std::uint64_t> alias;
    MetricValue value;
};

// The metrics of a command payload; an error when it is not a Sparkplug B payload. A Float value
// is the decimal its sender meant (12.3, not the 12.300000190734863 its 32 bits widen to).
Result<std::vector<CommandMetric>> decode_command(std::string_view payload);

// The text `loopwire write` takes for writing `value` to the metric ("150.5", "on"), or why it
// cannot be written (a bit of a bit field, the node's own metrics, a value of the wrong kind).
Result<std::string> write_text(const MetricDefinition& metric, const MetricValue& value);

// `value` in words for messages: 150.5, true, "on" (a text escaped and cut: it is a peer's), null.
std::string value_words(const MetricValue& value);

}  // namespace loopwire::gateway::sparkplug
