#include "shine/bench/bench_row.hpp"

#include <charconv>

#include "shine/core/error.hpp"

namespace shine {

std::string method_name(BenchMethod method) {
    return method == BenchMethod::kShineVdb ? "shinevdb" : "tsdf";
}

std::string method_label(BenchMethod method) {
    return method == BenchMethod::kShineVdb ? "ShineVDB" : "TSDF";
}

BenchMethod parse_method_name(const std::string& name) {
    if (name == "shinevdb") return BenchMethod::kShineVdb;
    if (name == "tsdf") return BenchMethod::kTsdf;
    throw DataError("unknown method '" + name + "' (expected shinevdb or tsdf)");
}

std::string format_size_m(double size_m) {
    char buffer[64];
    const auto result = std::to_chars(buffer, buffer + sizeof(buffer), size_m);
    std::string text(buffer, result.ptr);
    if (text.find_first_of(".en") == std::string::npos) text += ".0";
    return text;
}

}  // namespace shine
