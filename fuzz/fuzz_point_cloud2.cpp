// libFuzzer target: sensor_msgs/PointCloud2 messages. The first byte picks the serialisation
// (even: CDR, odd: ROS 1); the rest is the message.
#include "fuzz_common.hpp"
#include "shine/io/point_cloud2.hpp"
#include "shine/io/point_intensity.hpp"
#include "shine/io/preprocess.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    const shine::MessageEncoding encoding =
        data[0] % 2 == 0 ? shine::MessageEncoding::kCdr : shine::MessageEncoding::kRos1;
    shine_fuzz::expect_value_or_error([&] {
        const std::string where = shine_fuzz::kSource.string();
        const auto message = shine_fuzz::as_view(data + 1, size - 1);
        shine::decode_header_stamp_s(message, encoding, where);
        const shine::PointCloud2Scan scan = shine::decode_point_cloud2(message, encoding, where);
        if (!scan.point_time_s.empty() && scan.point_time_s.size() != scan.points_sensor.size()) {
            std::abort();  // one time per point, always
        }
        if (!scan.intensity.empty() && (scan.intensity.size() != scan.points_sensor.size() ||
                                        !shine::intensity_measured(scan.intensity))) {
            std::abort();  // one intensity per point, or none
        }
        shine::preprocess_scan(scan.points_sensor, shine::PreprocessConfig{}, shine_fuzz::kSource);
    });
    return 0;
}
