#pragma once
// Whether the device at a unit is the one its profile describes, judged from a read of the
// profile's identification words ("identification.match": a TC10's instrument code, an AC20's
// and the ramp/soak controller's fixed words). `loopwire read` and `write` check it before they
// talk to the device (DeviceClient::confirm_identity); the pollers of `loopwire monitor` and of
// the gateway read the words with a poll at start and after every outage and judge that poll by
// them, so a unit that answers as another device is shown `wrong-device` and none of its words
// are taken for values.
#include <string>
#include <vector>

#include "client/device_client.hpp"

namespace loopwire::device {

// The words a profile identifies its device by, in the profile's order; empty when it has none.
std::vector<const Parameter*> identification_words(const Profile& profile);

struct IdentityVerdict {
    enum class Kind {
        holds,    // every identification word read what the profile expects
        wrong,    // a word read something else, or the unit has no such word (exception 01h/02h)
        unknown,  // a word could not be read for another reason: the device is not judged
    };
    Kind kind = Kind::unknown;
    // For `wrong`: what was found, as "its instrument_id (word 0) reads -32768 where the tc10
    // profile expects 110"; for `unknown`, why the words could not be judged.
    std::string reason;
};

// Judges a read that asked for (at least) the profile's identification words. Exceptions other
// than 01h/02h leave the device unjudged: an AC20 in an error condition refuses everything but
// its menus with the condition's number (manual, ERROR REPLY), which does not say it is another
// device.
IdentityVerdict judge_identity(const Profile& profile, const ReadReport& report);

}  // namespace loopwire::device
