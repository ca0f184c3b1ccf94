#include "codec/device_identification.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace loopwire::codec {
namespace {

using ::testing::HasSubstr;

// The example of the Modbus application protocol V1.1b3, 6.21: a basic request for object 0
// and a reply carrying the three basic objects in one PDU.
const Bytes basic_request{0x2B, 0x0E, 0x01, 0x00};
const Bytes basic_reply{0x2B, 0x0E, 0x01, 0x01, 0x00, 0x00, 0x03,
                        0x00, 0x16, 'C', 'o', 'm', 'p', 'a', 'n', 'y', ' ', 'i', 'd', 'e', 'n', 't', 'i', 'f', 'i', 'c', 'a', 't', 'i', 'o', 'n',
                        0x01, 0x0F, 'P', 'r', 'o', 'd', 'u', 'c', 't', ' ', 'c', 'o', 'd', 'e', ' ', 'X', 'X',
                        0x02, 0x05, 'V', '2', '.', '1', '1'};

TEST(DeviceIdentification, RequestEncodesAndDecodes) {
    const DeviceIdentificationRequest request{IdentificationCategory::basic, 0};
    EXPECT_EQ(encode_device_identification_request(request), basic_request);
    auto decoded = decode_device_identification_request(basic_request);
    ASSERT_TRUE(decoded) << decoded.error().message;
    EXPECT_EQ(*decoded, request);
}

TEST(DeviceIdentification, TheStandardsExampleReplyDecodes) {
    auto reply = decode_device_identification_reply(basic_reply);
    ASSERT_TRUE(reply) << reply.error().message;
    EXPECT_EQ(reply->category, IdentificationCategory::basic);
    EXPECT_EQ(reply->conformity, 0x01);
    EXPECT_FALSE(reply->more_follows);
    ASSERT_EQ(reply->objects.size(), 3u);
    EXPECT_EQ(reply->objects[0], (IdentificationObject{0, "Company identification"}));
    EXPECT_EQ(reply->objects[1], (IdentificationObject{1, "Product code XX"}));
    EXPECT_EQ(reply->objects[2], (IdentificationObject{2, "V2.11"}));
    auto encoded = encode_device_identification_reply(*reply);
    ASSERT_TRUE(encoded) << encoded.error().message;
    EXPECT_EQ(*encoded, basic_reply);
}

TEST(DeviceIdentification, MoreFollowsAndTheNextObjectAreKept) {
    DeviceIdentification reply{IdentificationCategory::regular, 0x82, true, 0x05, {{0x03, "example.org"}}};
    auto encoded = encode_device_identification_reply(reply);
    ASSERT_TRUE(encoded) << encoded.error().message;
    EXPECT_EQ((*encoded)[4], 0xFF);
    EXPECT_EQ((*encoded)[5], 0x05);
    auto decoded = decode_device_identification_reply(*encoded);
    ASSERT_TRUE(decoded) << decoded.error().message;
    EXPECT_EQ(*decoded, reply);
}

TEST(DeviceIdentification, ObjectNames) {
    EXPECT_EQ(identification_object_name(0), "VendorName");
    EXPECT_EQ(identification_object_name(2), "MajorMinorRevision");
    EXPECT_EQ(identification_object_name(6), "UserApplicationName");
    EXPECT_EQ(identification_object_name(0x80), "object 0x80");
}

struct BadPdu {
    Bytes pdu;
    const char* says;
};

class DeviceIdentificationBadReplies : public ::testing::TestWithParam<BadPdu> {};

TEST_P(DeviceIdentificationBadReplies, AreMalformedSayingWhy) {
    auto reply = decode_device_identification_reply(GetParam().pdu);
    ASSERT_FALSE(reply);
    EXPECT_EQ(reply.error().kind, ErrorKind::malformed);
    EXPECT_THAT(reply.error().message, HasSubstr(GetParam().says));
}

INSTANTIATE_TEST_SUITE_P(
    Every, DeviceIdentificationBadReplies,
    ::testing::Values(BadPdu{{0x2B, 0x0E, 0x01}, "at least 7"},
                      BadPdu{{0x03, 0x0E, 0x01, 0x01, 0x00, 0x00, 0x00}, "function 3, not 43"},
                      BadPdu{{0x2B, 0x0D, 0x01, 0x01, 0x00, 0x00, 0x00}, "MEI type 13, not 14"},
                      BadPdu{{0x2B, 0x0E, 0x05, 0x01, 0x00, 0x00, 0x00}, "code 5 is not 1 to 4"},
                      BadPdu{{0x2B, 0x0E, 0x01, 0x01, 0x01, 0x00, 0x00}, "more-follows byte 01h"},
                      BadPdu{{0x2B, 0x0E, 0x01, 0x01, 0x00, 0x00, 0x01, 0x00}, "ends inside object 1 of 1"},
                      BadPdu{{0x2B, 0x0E, 0x01, 0x01, 0x00, 0x00, 0x01, 0x00, 0x03, 'a'}, "VendorName says 3 bytes, 1 are left"},
                      BadPdu{{0x2B, 0x0E, 0x01, 0x01, 0x00, 0x00, 0x00, 0x99}, "1 bytes after the 0 objects"}));

TEST(DeviceIdentification, BadRequestsAreMalformed) {
    EXPECT_FALSE(decode_device_identification_request(Bytes{0x2B, 0x0E, 0x01}));
    EXPECT_FALSE(decode_device_identification_request(Bytes{0x2B, 0x0E, 0x00, 0x00}));
    EXPECT_FALSE(decode_device_identification_request(Bytes{0x2B, 0x0E, 0x01, 0x00, 0x00}));
}

TEST(DeviceIdentification, ObjectsThatDoNotFitOnePduAreRefused) {
    DeviceIdentification reply;
    reply.objects = {{0, std::string(200, 'a')}, {1, std::string(60, 'b')}};
    auto encoded = encode_device_identification_reply(reply);
    ASSERT_FALSE(encoded);
    EXPECT_EQ(encoded.error().kind, ErrorKind::usage);
    reply.objects = {{0, std::string(256, 'a')}};
    EXPECT_FALSE(encode_device_identification_reply(reply));
}

}  // namespace
}  // namespace loopwire::codec
