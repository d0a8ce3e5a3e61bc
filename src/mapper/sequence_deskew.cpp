// Deskewing the scans of a sequence while mapping.
#include "shine/mapper/sequence_deskew.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "shine/core/error.hpp"
#include "shine/odometry/scan_deskew.hpp"

namespace shine {

const char* to_string(DeskewMode mode) {
    switch (mode) {
        case DeskewMode::kAuto:
            return "auto";
        case DeskewMode::kOn:
            return "on";
        case DeskewMode::kOff:
            return "off";
    }
    return "?";
}

bool deskew_active(const DeskewConfig& config, bool estimate_poses, bool sweep_times) {
    return config.mode == DeskewMode::kOn ||
           (config.mode == DeskewMode::kAuto && (estimate_poses || sweep_times));
}

void require_point_times(const Scan& scan) {
    if (scan.point_time_s.empty() && !scan.points_sensor.empty()) {
        throw DataError("scan '" + scan.source.string() +
                        "' has no per-point times, which --deskew needs: its points need a field "
                        "t, time, timestamp or offset_time (PLY, PCD or a recording's "
                        "PointCloud2; KITTI .bin has none); map without --deskew");
    }
}

double scan_interval_s(const ScanSequence& sequence, std::size_t a, std::size_t b,
                       double scan_period_s) {
    double interval_s = 0.0;
    if (sequence.from_recording()) {
        interval_s = sequence.stamp_s(b) - sequence.stamp_s(a);
    } else {
        interval_s = scan_period_s * (static_cast<double>(sequence.frame_number(b)) -
                                      static_cast<double>(sequence.frame_number(a)));
    }
    if (!(interval_s > 0.0)) {
        char text[64];
        std::snprintf(text, sizeof(text), "%.9g", interval_s);
        throw DataError("scans '" + sequence.scan_path(a).string() + "' and '" +
                        sequence.scan_path(b).string() + "' are " + text +
                        " s apart: deskewing needs increasing scan times");
    }
    return interval_s;
}

double deskew_in_place(Scan& scan, const Eigen::Isometry3d& T_prev_cur, double interval_s,
                       DeskewStats& stats) {
    return deskew_in_place(scan, T_prev_cur, interval_s, T_prev_cur, interval_s, stats);
}

double deskew_in_place(Scan& scan, const Eigen::Isometry3d& T_prev_cur, double interval_prev_s,
                       const Eigen::Isometry3d& T_cur_next, double interval_next_s,
                       DeskewStats& stats) {
    // The sensor's position at each point's time, moved the same way: the points' ray origins.
    std::vector<Eigen::Vector3f> origins;
    std::vector<Eigen::Vector3f> moved =
        deskew_scan_between(scan.points_sensor, scan.point_time_s, T_prev_cur, interval_prev_s,
                            T_cur_next, interval_next_s, &origins);
    double max_shift_m = 0.0;
    for (std::size_t i = 0; i < moved.size(); ++i) {
        const double shift = static_cast<double>((moved[i] - scan.points_sensor[i]).norm());
        if (std::isfinite(shift)) max_shift_m = std::max(max_shift_m, shift);  // NaN stays NaN
    }
    scan.points_sensor = std::move(moved);
    scan.point_origin_sensor = std::move(origins);
    if (stats.scans_deskewed == 0) stats.time_format = scan.point_time_format;
    ++stats.scans_deskewed;
    stats.max_shift_m = std::max(stats.max_shift_m, max_shift_m);
    return max_shift_m;
}

void deskew_with_sequence_poses(Scan& scan, const ScanSequence& sequence, std::size_t i,
                                const DeskewConfig& config, DeskewStats& stats) {
    if (config.mode == DeskewMode::kOn) require_point_times(scan);
    if (scan.point_time_s.empty() || sequence.size() < 2) {
        ++stats.scans_as_measured;
        return;
    }
    // The motion from the previous pose and to the next one; at either end of the sequence the
    // one that exists serves both sides.
    const auto motion = [&](std::size_t a, std::size_t b) {
        return std::make_pair(sequence.pose(a).inverse() * sequence.pose(b),
                              scan_interval_s(sequence, a, b, config.scan_period_s));
    };
    const auto before = i > 0 ? motion(i - 1, i) : motion(i, i + 1);
    const auto after = i + 1 < sequence.size() ? motion(i, i + 1) : before;
    deskew_in_place(scan, before.first, before.second, after.first, after.second, stats);
}

}  // namespace shine
