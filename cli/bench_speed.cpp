#include "bench_speed.hpp"

#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/median.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

std::string quoted(const std::string& s) {
    std::string out = "'";
    for (const char c : s) {
        if (c == '\'') {
            out += "'\\''";
        } else {
            out += c;
        }
    }
    return out + "'";
}

std::string ms(double seconds) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.0f ms", 1000.0 * seconds);
    return buf;
}

std::string secs(double seconds) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.1f s", seconds);
    return buf;
}

std::string ratio(double r) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.2f", r);
    return buf;
}

/// "median (min-max)" of `v` formatted by `f`.
template <class F>
std::string with_range(const std::vector<double>& v, F f) {
    if (v.empty()) return "—";
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    if (v.size() == 1) return f(v[0]);
    return f(median(v)) + " (" + f(*lo) + "–" + f(*hi) + ")";
}

/// The `shine` executable running this process (the runs must use the same build).
fs::path self_executable() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec || exe.empty()) {
        throw Error("bench --speed: cannot find the shine executable (/proc/self/exe): " +
                    ec.message());
    }
    return exe;
}

nlohmann::json read_stats(const fs::path& run_dir) {
    std::ifstream in(run_dir / "stats.json");
    if (!in) throw Error("bench --speed: '" + (run_dir / "stats.json").string() + "' is missing");
    return nlohmann::json::parse(in);
}

struct RunResult {
    double wall_s = 0.0;
    double per_scan_s = 0.0;       ///< 0 when the method has no per-scan time (batch)
    double mean_per_scan_s = 0.0;  ///< "no poses" only
};

RunResult run_one(const SpeedStudyOptions& o, const fs::path& exe, const std::string& method,
                  int round) {
    std::string name = method;
    std::replace(name.begin(), name.end(), ' ', '_');
    const fs::path dir = o.out / "speed" / (name + "_" + std::to_string(round));
    std::error_code ignored;
    fs::remove_all(dir, ignored);
    fs::create_directories(dir.parent_path());
    const std::string common = " -o " + quoted(dir.string()) + " --threads " +
                               std::to_string(o.threads) + " -q --no-eval " + o.selection_args;
    std::string cmd = quoted(exe.string());
    if (method == "tsdf") {
        char voxel[64];
        std::snprintf(voxel, sizeof(voxel), " --voxel-size-m %g --trunc-m %g", o.tsdf_voxel_m,
                      3.0 * o.tsdf_voxel_m);
        cmd += " tsdf " + quoted(o.data.string()) + common + voxel + " --voxel-downsample-m 0";
    } else {
        cmd += " map " + quoted(o.data.string()) + common + " " + o.shine_args;
        if (method == "incremental") cmd += " --mode incremental";
        if (method == "no poses") cmd += " --mode incremental --poses estimate";
    }
    const fs::path log = o.out / "speed" / (name + "_" + std::to_string(round) + ".log");
    cmd += " > " + quoted(log.string()) + " 2>&1";

    const auto start = std::chrono::steady_clock::now();
    const int status = std::system(cmd.c_str());
    RunResult r;
    r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (status == -1 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        throw Error("bench --speed: the " + method + " run of round " + std::to_string(round) +
                    " failed; its output is in '" + log.string() + "'");
    }
    const nlohmann::json stats = read_stats(dir);
    if (method == "tsdf") {
        const double frames = stats.at("frames").get<double>();
        r.per_scan_s = frames > 0 ? stats.at("seconds").at("integrate").get<double>() / frames : 0;
    } else if (method == "incremental") {
        r.per_scan_s = stats.at("incremental").at("median_seconds_per_frame").get<double>();
    } else if (method == "no poses") {
        r.per_scan_s = stats.at("odometry").at("median_seconds_per_scan").get<double>();
        r.mean_per_scan_s = stats.at("keyframes").at("mean_seconds_per_scan").get<double>();
    }
    return r;
}

}  // namespace

std::vector<SpeedRow> run_speed_study(const SpeedStudyOptions& o) {
    if (o.rounds < 1) throw ConfigError("bench --speed: --rounds must be at least 1");
    const fs::path exe = self_executable();
    const std::vector<std::string> methods =
        o.data_has_poses ? std::vector<std::string>{"tsdf", "batch", "incremental", "no poses"}
                         : std::vector<std::string>{"no poses"};
    std::vector<SpeedRow> rows(methods.size());
    for (std::size_t m = 0; m < methods.size(); ++m) rows[m].method = methods[m];
    for (int round = 1; round <= o.rounds; ++round) {
        // A rotating order: no method always runs first (cold caches) or last (a warm machine).
        for (std::size_t k = 0; k < methods.size(); ++k) {
            const std::size_t m = (k + static_cast<std::size_t>(round - 1)) % methods.size();
            if (!o.quiet) {
                std::fprintf(stderr, "bench --speed: round %d/%d, %s\n", round, o.rounds,
                             methods[m].c_str());
            }
            const RunResult r = run_one(o, exe, methods[m], round);
            rows[m].wall_seconds.push_back(r.wall_s);
            if (r.per_scan_s > 0.0) rows[m].per_scan_seconds.push_back(r.per_scan_s);
            if (r.mean_per_scan_s > 0.0) {
                rows[m].mean_per_scan_seconds.push_back(r.mean_per_scan_s);
            }
        }
    }

    nlohmann::json j;
    j["data"] = o.data.string();
    j["rounds"] = o.rounds;
    j["threads"] = o.threads;
    j["tsdf_voxel_m"] = o.tsdf_voxel_m;
    j["shine_args"] = o.shine_args;
    for (const SpeedRow& row : rows) {
        j["methods"][row.method] = {{"wall_seconds", row.wall_seconds},
                                    {"per_scan_seconds", row.per_scan_seconds},
                                    {"mean_per_scan_seconds", row.mean_per_scan_seconds}};
    }
    write_stream_atomically(o.out / "speed.json", [&](std::ostream& os) { os << j.dump(2); });
    write_stream_atomically(o.out / "speed.md",
                            [&](std::ostream& os) { os << format_speed_table(rows); });
    return rows;
}

std::string format_speed_table(const std::vector<SpeedRow>& rows) {
    const SpeedRow* tsdf = nullptr;
    for (const SpeedRow& r : rows) {
        if (r.method == "tsdf") tsdf = &r;
    }
    // Ratios within each round (the runs of a round are neighbours in time).
    const auto round_ratios = [](const std::vector<double>& a, const std::vector<double>& b) {
        std::vector<double> out;
        for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
            if (b[i] > 0.0) out.push_back(a[i] / b[i]);
        }
        return out;
    };
    std::ostringstream s;
    s << "| run | median per scan | mean per scan | whole run | whole run / TSDF | per scan / "
         "TSDF |\n"
      << "| --- | --- | --- | --- | --- | --- |\n";
    for (const SpeedRow& r : rows) {
        s << "| " << r.method << " | " << with_range(r.per_scan_seconds, ms) << " | "
          << with_range(r.mean_per_scan_seconds, ms) << " | " << with_range(r.wall_seconds, secs)
          << " | ";
        if (tsdf && &r != tsdf) {
            s << with_range(round_ratios(r.wall_seconds, tsdf->wall_seconds), ratio) << " | "
              << with_range(round_ratios(r.per_scan_seconds, tsdf->per_scan_seconds), ratio);
        } else {
            s << "— | —";
        }
        s << " |\n";
    }
    return s.str();
}

}  // namespace shine::cli
