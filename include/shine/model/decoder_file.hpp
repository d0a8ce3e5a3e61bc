// Decoder weights on their own, as a small YAML text file: the pretrained decoder that incremental
// mode loads frozen (paper Sec. III-A: "In case we map incrementally, we ... use a pre-trained
// MLP and keep it fixed"), written by `shine pretrain` and shipped as
// models/decoder_pretrained.yaml, which the build compiles into the library.
//
//   format: shinevdb-decoder
//   version: 1
//   input_dim: 8
//   hidden_dims: [32, 32]
//   provenance: "how it was made"
//   params: [...]          # Decoder::params() order, 9 significant digits (exact for float)
#pragma once

#include <filesystem>
#include <string>

#include "shine/model/decoder.hpp"

namespace shine {

/// The decoder as YAML text; `provenance` (e.g. the command that made it) is stored with it.
std::string decoder_to_yaml(const Decoder& decoder, const std::string& provenance);

/// A decoder with the weights of `text`. Throws IoError naming `source` for text that is not a
/// decoder file or whose weight count does not match its shape.
Decoder decoder_from_yaml(const std::string& text, const std::string& source);

/// The provenance string stored in decoder YAML text ("" if none).
std::string decoder_provenance(const std::string& text, const std::string& source);

/// Writes decoder_to_yaml() to `path` atomically. Throws IoError naming the file on failure.
void save_decoder(const std::filesystem::path& path, const Decoder& decoder,
                  const std::string& provenance);

/// Reads a file written by save_decoder(). Throws IoError naming the file.
Decoder load_decoder(const std::filesystem::path& path);

/// The text of models/decoder_pretrained.yaml as it was when the library was built; empty if the
/// file did not exist then.
const char* builtin_decoder_yaml();
/// The same for models/decoder_pretrained_fine.yaml, the decoder pretrained at 0.1 m leaves.
const char* builtin_fine_decoder_yaml();

}  // namespace shine
