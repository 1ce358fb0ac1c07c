#pragma once

#include <cmath>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"

/// Reading objscan's JSON results files with errors that name the file and the key.
namespace objscan::report::json_node {

using Json = nlohmann::json;

/// The text of `path` parsed; InputError naming it when it is not JSON.
inline Json parseText(const std::string& text, const std::filesystem::path& path) {
  try {
    return Json::parse(text);
  } catch (const Json::exception& e) {  // syntax errors, truncation, numbers out of range
    throw InputError(path, std::string("not valid JSON: ") + e.what());
  }
}

/// The file parsed; InputError naming it when it is missing, unreadable or not JSON.
inline Json parseFile(const std::filesystem::path& path) {
  return parseText(readWholeFile(path), path);
}

inline const char* typeName(const Json& j) {
  switch (j.type()) {
    case Json::value_t::object:
      return "an object";
    case Json::value_t::array:
      return "an array";
    case Json::value_t::string:
      return "a string";
    case Json::value_t::boolean:
      return "a boolean";
    case Json::value_t::number_integer:
    case Json::value_t::number_unsigned:
    case Json::value_t::number_float:
      return "a number";
    default:
      return "null";
  }
}

/// One JSON object of an input file and where it sits in the file ("hypotheses[3].box"), so that a
/// value of the wrong type is reported with the file and the key. A key that is absent or null
/// reads as unknown (std::nullopt); require() turns that into an error.
class Node {
 public:
  Node(const std::filesystem::path& file, const Json& json, std::string where)
      : file_(&file), json_(&json), where_(std::move(where)) {
    if (!json_->is_object())
      fail(where_, std::string("is ") + typeName(*json_) + ", not an object");
  }

  [[noreturn]] void fail(const std::string& key, const std::string& problem) const {
    throw InputError(
        *file_, (key.empty() ? std::string("the top level") : "\"" + key + "\"") + " " + problem);
  }

  std::string keyPath(const char* key) const {
    return where_.empty() ? std::string(key) : where_ + "." + key;
  }

  /// nullptr when `key` is absent or null.
  const Json* get(const char* key) const {
    const auto it = json_->find(key);
    return it == json_->end() || it->is_null() ? nullptr : &*it;
  }

  template <typename T>
  T require(const char* key, const std::optional<T>& value) const {
    if (!value) fail(keyPath(key), "is missing (not a file this objscan writes, or damaged)");
    return *value;
  }

  std::optional<double> number(const char* key) const {
    const Json* j = get(key);
    if (j == nullptr) return std::nullopt;
    return expect(key, j->is_number(), "a number").get<double>();
  }

  std::optional<std::int64_t> integer(const char* key) const {
    const Json* j = get(key);
    if (j == nullptr) return std::nullopt;
    expect(key, j->is_number(), "a whole number");
    if (j->is_number_integer()) return j->get<std::int64_t>();
    const double v = j->get<double>();
    if (v != std::floor(v) || std::abs(v) > 9e15) fail(keyPath(key), "is not a whole number");
    return static_cast<std::int64_t>(v);
  }

  /// A whole number of at least 0.
  std::optional<std::size_t> count(const char* key) const {
    const std::optional<std::int64_t> v = integer(key);
    if (!v) return std::nullopt;
    if (*v < 0) fail(keyPath(key), "is negative");
    return static_cast<std::size_t>(*v);
  }

  std::optional<std::string> string(const char* key) const {
    const Json* j = get(key);
    if (j == nullptr) return std::nullopt;
    return expect(key, j->is_string(), "a string").get<std::string>();
  }

  std::optional<bool> boolean(const char* key) const {
    const Json* j = get(key);
    if (j == nullptr) return std::nullopt;
    return expect(key, j->is_boolean(), "true or false").get<bool>();
  }

  std::optional<Node> object(const char* key) const {
    const Json* j = get(key);
    if (j == nullptr) return std::nullopt;
    expect(key, j->is_object(), "an object");
    return Node(*file_, *j, keyPath(key));
  }

  /// The elements of the array at `key`, each required to be an object; empty when absent.
  std::vector<Node> objects(const char* key) const {
    std::vector<Node> out;
    const Json* j = get(key);
    if (j == nullptr) return out;
    expect(key, j->is_array(), "an array");
    for (std::size_t i = 0; i < j->size(); ++i) {
      out.emplace_back(*file_, (*j)[i], keyPath(key) + "[" + std::to_string(i) + "]");
    }
    return out;
  }

  std::vector<std::string> strings(const char* key) const {
    std::vector<std::string> out;
    const Json* j = get(key);
    if (j == nullptr) return out;
    expect(key, j->is_array(), "an array of strings");
    for (const Json& e : *j) {
      if (!e.is_string())
        fail(keyPath(key), "holds " + std::string(typeName(e)) + ", not a string");
      out.push_back(e.get<std::string>());
    }
    return out;
  }

  /// An array of `n` numbers at `key`; nothing when absent.
  std::optional<std::vector<double>> numbers(const char* key, std::size_t n) const {
    const Json* j = get(key);
    if (j == nullptr) return std::nullopt;
    return numbersIn(*j, keyPath(key), n);
  }

  std::vector<double> numbersIn(const Json& j, const std::string& where, std::size_t n) const {
    if (!j.is_array() || j.size() != n)
      fail(where, "is not an array of " + std::to_string(n) + " numbers");
    std::vector<double> out;
    for (const Json& e : j) {
      if (!e.is_number()) fail(where, "is not an array of " + std::to_string(n) + " numbers");
      out.push_back(e.get<double>());
    }
    return out;
  }

  const Json& json() const { return *json_; }

 private:
  const Json& expect(const char* key, bool ok, const char* wanted) const {
    const Json& j = json_->at(key);
    if (!ok) fail(keyPath(key), std::string("is ") + typeName(j) + ", expected " + wanted);
    return j;
  }

  const std::filesystem::path* file_;
  const Json* json_;
  std::string where_;
};

}  // namespace objscan::report::json_node
