#include "shine/bench/bench_row.hpp"

#include <charconv>

#include "shine/core/error.hpp"

namespace shine {

std::string method_name(BenchMethod method) {
    switch (method) {
        case BenchMethod::kShineVdb:
            return "shinevdb";
        case BenchMethod::kTsdf:
            return "tsdf";
        case BenchMethod::kShineVdbIncremental:
            return "shinevdb_incremental";
    }
    throw Error("method_name: unknown BenchMethod");
}

std::string method_label(BenchMethod method) {
    switch (method) {
        case BenchMethod::kShineVdb:
            return "ShineVDB";
        case BenchMethod::kTsdf:
            return "TSDF";
        case BenchMethod::kShineVdbIncremental:
            return "ShineVDB incremental";
    }
    throw Error("method_label: unknown BenchMethod");
}

BenchMethod parse_method_name(const std::string& name) {
    for (const BenchMethod method :
         {BenchMethod::kShineVdb, BenchMethod::kTsdf, BenchMethod::kShineVdbIncremental}) {
        if (name == method_name(method)) return method;
    }
    throw DataError("unknown method '" + name +
                    "' (expected shinevdb, tsdf or shinevdb_incremental)");
}

std::string format_size_m(double size_m) {
    char buffer[64];
    const auto result = std::to_chars(buffer, buffer + sizeof(buffer), size_m);
    std::string text(buffer, result.ptr);
    if (text.find_first_of(".en") == std::string::npos) text += ".0";
    return text;
}

}  // namespace shine
