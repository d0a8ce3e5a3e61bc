#include "shine/model/decoder_file.hpp"

#include <yaml-cpp/yaml.h>

#include <fstream>
#include <limits>
#include <sstream>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace {
constexpr const char* kFormat = "shinevdb-decoder";
constexpr int kVersion = 1;

YAML::Node parse(const std::string& text, const std::string& source) {
    YAML::Node root;
    try {
        root = YAML::Load(text);
    } catch (const YAML::Exception& e) {
        throw IoError("decoder weights '" + source + "' are not valid YAML: " + e.what());
    }
    if (!root.IsMap() || !root["format"] || root["format"].as<std::string>("") != kFormat) {
        throw IoError("'" + source + "' is not a ShineVDB decoder file (expected 'format: " +
                      kFormat + "'); write one with `shine pretrain -o FILE`");
    }
    return root;
}
}  // namespace

std::string decoder_to_yaml(const Decoder& decoder, const std::string& provenance) {
    YAML::Emitter out;
    out.SetFloatPrecision(std::numeric_limits<float>::max_digits10);
    out << YAML::BeginMap;
    out << YAML::Key << "format" << YAML::Value << kFormat;
    out << YAML::Key << "version" << YAML::Value << kVersion;
    out << YAML::Key << "input_dim" << YAML::Value << decoder.config().input_dim;
    out << YAML::Key << "hidden_dims" << YAML::Value << YAML::Flow << decoder.config().hidden_dims;
    out << YAML::Key << "provenance" << YAML::Value << YAML::DoubleQuoted << provenance;
    out << YAML::Key << "params" << YAML::Value << YAML::Flow << decoder.params();
    out << YAML::EndMap;
    return std::string(out.c_str()) + "\n";
}

Decoder decoder_from_yaml(const std::string& text, const std::string& source) {
    const YAML::Node root = parse(text, source);
    try {
        if (root["version"].as<int>() != kVersion) {
            throw IoError("decoder weights '" + source + "': unsupported version " +
                          root["version"].as<std::string>());
        }
        DecoderConfig config;
        config.input_dim = root["input_dim"].as<int>();
        config.hidden_dims = root["hidden_dims"].as<std::vector<int>>();
        const std::vector<float> params = root["params"].as<std::vector<float>>();
        Decoder decoder(config);
        if (params.size() != decoder.num_params()) {
            throw IoError("decoder weights '" + source + "': " + std::to_string(params.size()) +
                          " weights, but the shape needs " + std::to_string(decoder.num_params()));
        }
        decoder.params() = params;
        return decoder;
    } catch (const YAML::Exception& e) {
        throw IoError("decoder weights '" + source + "': missing or malformed field (" + e.what() +
                      ")");
    } catch (const ConfigError& e) {
        throw IoError("decoder weights '" + source + "': " + e.what());
    }
}

std::string decoder_provenance(const std::string& text, const std::string& source) {
    const YAML::Node root = parse(text, source);
    return root["provenance"] ? root["provenance"].as<std::string>("") : "";
}

void save_decoder(const std::filesystem::path& path, const Decoder& decoder,
                  const std::string& provenance) {
    const std::string text = decoder_to_yaml(decoder, provenance);
    write_stream_atomically(path, [&](std::ostream& out) { out << text; });
}

Decoder load_decoder(const std::filesystem::path& path) {
    std::ifstream in(path);
    if (!in) throw IoError("cannot open decoder weights '" + path.string() + "'");
    std::stringstream text;
    text << in.rdbuf();
    return decoder_from_yaml(text.str(), path.string());
}

}  // namespace shine
