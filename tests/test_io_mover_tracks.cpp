// The movers of simulation.json: round trip, interpolation, and errors that name the file and key.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "shine/core/error.hpp"
#include "shine/io/mover_tracks.hpp"

namespace shine {
namespace {

constexpr double kTolM = 1e-12;

MoverTracks two_movers() {
    MoverTracks tracks;
    tracks.frame_period_s = 0.1;
    tracks.sweep_s = 0.1;
    tracks.num_frames = 30;
    MoverTrack car;
    car.kind = MoverKind::kCar;
    car.waypoints = {{0.0, {0.0, -2.3, 0.0}, 0.0}, {3.0, {30.0, -2.3, 0.0}, 0.0}};
    MoverTrack walker;
    walker.kind = MoverKind::kPedestrian;
    walker.size_m = {0.5, 0.5, 1.8};
    walker.waypoints = {{0.0, {5.0, 7.2, 0.15}, M_PI}, {1.0, {4.0, 7.2, 0.15}, M_PI / 3.0}};
    tracks.movers = {car, walker};
    return tracks;
}

std::string document(const std::string& movers) {
    return "{\"seed\": 1, \"movers\": " + movers + "}";
}

TEST(MoverTracks, RoundTripIsExact) {
    const MoverTracks tracks = two_movers();
    const MoverTracks back = parse_mover_tracks(document(mover_tracks_to_json(tracks)), "s.json");
    ASSERT_EQ(back.movers.size(), 2u);
    EXPECT_EQ(back.num_frames, 30);
    EXPECT_EQ(back.frame_period_s, 0.1);
    EXPECT_EQ(back.movers[1].kind, MoverKind::kPedestrian);
    EXPECT_EQ(back.movers[1].size_m, tracks.movers[1].size_m);
    ASSERT_EQ(back.movers[1].waypoints.size(), 2u);
    EXPECT_EQ(back.movers[1].waypoints[1].yaw_rad, M_PI / 3.0);
    EXPECT_EQ(back.movers[0].waypoints[1].position_m, tracks.movers[0].waypoints[1].position_m);
}

TEST(MoverTracks, PoseInterpolatesAndHoldsOutsideThePath) {
    const MoverTrack car = two_movers().movers[0];
    EXPECT_NEAR(car.T_world_body(1.5).translation().x(), 15.0, kTolM);
    EXPECT_NEAR(car.T_world_body(-1.0).translation().x(), 0.0, kTolM);
    EXPECT_NEAR(car.T_world_body(9.0).translation().x(), 30.0, kTolM);
    const MoverTrack walker = two_movers().movers[1];
    const Eigen::Matrix3d R = walker.T_world_body(0.5).linear();
    const double yaw = std::atan2(R(1, 0), R(0, 0));
    EXPECT_NEAR(yaw, (M_PI + M_PI / 3.0) / 2.0, 1e-12);
}

/// parse_mover_tracks must throw DataError whose message holds `source` and `key`.
void expect_error(const std::string& text, const std::string& key) {
    try {
        parse_mover_tracks(text, "dir/simulation.json");
        FAIL() << "no error for " << text;
    } catch (const DataError& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("dir/simulation.json"), std::string::npos) << message;
        EXPECT_NE(message.find(key), std::string::npos) << message;
    }
}

TEST(MoverTracks, BadInputNamesFileAndKey) {
    expect_error("{\"seed\": 1", "not valid JSON");
    expect_error("{\"seed\": 1}", "without movers");
    expect_error(document("{\"sweep_s\": 0.1, \"num_frames\": 3, \"list\": []}"),
                 "movers.frame_period_s is missing");
    expect_error(document("{\"frame_period_s\": -1, \"sweep_s\": 0.1, \"num_frames\": 3, "
                          "\"list\": []}"),
                 "frame_period_s must be positive");
    const std::string head = "{\"frame_period_s\": 0.1, \"sweep_s\": 0.1, \"num_frames\": 3, ";
    expect_error(document(head + "\"list\": [{\"kind\": \"tram\", \"size_m\": [1, 1, 1], "
                                 "\"waypoints\": []}]}"),
                 "list[0].kind");
    expect_error(document(head + "\"list\": [{\"kind\": \"car\", \"size_m\": [1, 0, 1], "
                                 "\"waypoints\": []}]}"),
                 "size_m must be positive");
    expect_error(document(head + "\"list\": [{\"kind\": \"car\", \"size_m\": [1, 1, 1], "
                                 "\"waypoints\": []}]}"),
                 "waypoints must be a non-empty array");
    expect_error(document(head + "\"list\": [{\"kind\": \"car\", \"size_m\": [1, 1, 1], "
                                 "\"waypoints\": [{\"t_s\": 1, \"position_m\": [0, 0, 0], "
                                 "\"yaw_rad\": 0}, {\"t_s\": 1, \"position_m\": [1, 0, 0], "
                                 "\"yaw_rad\": 0}]}]}"),
                 "waypoints[1].t_s must be later");
    expect_error(document(head + "\"list\": [{\"kind\": \"car\", \"size_m\": [1, 1, 1], "
                                 "\"waypoints\": [{\"t_s\": 0, \"position_m\": [0, \"x\", 0], "
                                 "\"yaw_rad\": 0}]}]}"),
                 "position_m[1] must be a number");
}

TEST(MoverTracks, MissingFileIsAnIoError) {
    EXPECT_THROW(read_mover_tracks("/nonexistent/simulation.json"), IoError);
}

}  // namespace
}  // namespace shine
