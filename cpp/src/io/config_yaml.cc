#include "linnet/io/config_yaml.h"

#include <cstdio>
#include <filesystem>
#include <set>

namespace linnet {
namespace {

std::string joinAllowed(std::initializer_list<const char*> allowed, const char* sep) {
  std::string list;
  for (const char* a : allowed) list += std::string(list.empty() ? "" : sep) + a;
  return list;
}

}  // namespace

YamlOptionsReader::YamlOptionsReader(const YAML::Node& node, std::string source, std::string prefix)
    : node_(node), source_(std::move(source)), prefix_(std::move(prefix)) {
  if (node_.IsDefined() && !node_.IsNull() && !node_.IsMap()) {
    const std::string what = prefix_.empty() ? "the document" : "key '" + prefix_ + "'";
    throw ConfigError(yaml::where(source_, node_) + ": " + what + " must be a map of options, got " +
                      yaml::describe(node_));
  }
}

YAML::Node YamlOptionsReader::find(const char* key) {
  known_.emplace_back(key);
  if (!node_.IsDefined() || !node_.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
  const YAML::Node& const_node = node_;  // const lookup: never inserts
  return const_node[key];
}

void YamlOptionsReader::choice(const char* key, std::string& value, const char* /*doc*/,
                               std::initializer_list<const char*> allowed) {
  const YAML::Node n = find(key);
  if (!n) return;
  const yaml::Context ctx = context(key);
  std::string v;
  yaml::decode(n, ctx, v);
  for (const char* a : allowed) {
    if (v == a) {
      value = v;
      return;
    }
  }
  std::vector<std::string> names(allowed.begin(), allowed.end());
  const std::string guess = yaml::closestName(v, names);
  ctx.fail(n, "= '" + v + "' is not one of {" + joinAllowed(allowed, ", ") + "}" +
                  (guess.empty() ? "" : " (did you mean '" + guess + "'?)"));
}

void YamlOptionsReader::finish() const {
  if (!node_.IsDefined() || !node_.IsMap()) return;
  std::set<std::string> seen;
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const YAML::Node k = it->first;
    if (!k.IsScalar()) {
      throw ConfigError(yaml::where(source_, k) + ": " +
                        (prefix_.empty() ? "top level" : "in '" + prefix_ + "'") +
                        ": keys must be plain names, got " + yaml::describe(k));
    }
    const std::string name = k.Scalar();
    const std::string full = prefix_.empty() ? name : prefix_ + "." + name;
    if (!seen.insert(name).second)
      throw ConfigError(yaml::where(source_, k) + ": duplicate key '" + full + "'");
    if (std::find(known_.begin(), known_.end(), name) != known_.end()) continue;
    std::string msg = yaml::where(source_, k) + ": unknown key '" + full + "'";
    const std::string guess = yaml::closestName(name, known_);
    if (!guess.empty()) {
      msg += " (did you mean '" + guess + "'?)";
    } else if (!known_.empty() && known_.size() <= 16) {
      msg += " (known keys" + (prefix_.empty() ? std::string() : " in '" + prefix_ + "'") + ": ";
      for (std::size_t i = 0; i < known_.size(); ++i) msg += (i ? ", " : "") + known_[i];
      msg += ")";
    }
    throw ConfigError(msg);
  }
}

void YamlOptionsWriter::choice(const char* key, std::string& value, const char* doc,
                               std::initializer_list<const char*> allowed) {
  out_ << YAML::Key << key << YAML::Value;
  yaml::encode(out_, value);
  comment(std::string(doc) + " {" + joinAllowed(allowed, " | ") + "}");
}

void YamlOptionsWriter::comment(const std::string& doc) {
  if (comments_ && !doc.empty()) out_ << YAML::Comment(doc);
}

YAML::Node loadYamlFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) io::failInput(path, 0, "file not found");
  if (std::filesystem::is_directory(path, ec)) io::failInput(path, 0, "is a directory, expected a YAML file");
  try {
    return YAML::LoadFile(path);
  } catch (const YAML::ParserException& e) {
    io::failInput(path, e.mark.line + 1, "YAML syntax error: " + e.msg);
  } catch (const YAML::BadFile&) {
    io::failInput(path, 0, "cannot open file for reading");
  }
}

void writeTextFile(const std::string& path, const std::string& text) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) io::failInput(path, 0, "cannot open file for writing");
  const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  const bool closed = std::fclose(f) == 0;
  if (!ok || !closed) io::failInput(path, 0, "write failed (disk full?)");
}

}  // namespace linnet
