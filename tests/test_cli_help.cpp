// Every page of `stylerf`'s help, walked as a new user would: `stylerf help`, `stylerf --version`, and the --help
// of each command it lists and of each `eval` subcommand. Each page must answer with status 0 and end with an
// "Examples:" block; each default must be printed as a user would type it; and the names the command-line
// grammar fixes must mean the same thing on every page (a table name -> pages built from all of them).
#include <doctest/doctest.h>

#include <cstdlib>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "tests/cli_runner.hpp"

namespace {

using stylerf::testing::CliRun;
using stylerf::testing::run_cli;

bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// One option as a --help page shows it.
struct Option {
  std::string page;           // "eval table"
  std::string name;           // "--depth-tol"
  std::string short_name;     // "-o", or empty
  bool takes_value = false;   // "arg" after the name
  bool has_default = false;   // "(=...)" after it
  std::string default_text;   // what is inside "(=...)"
  std::string text;           // the description, its wrapped lines joined
};

// boost::program_options' layout: "  -o [ --output ] arg (=x)   text" or "  --name arg   text", the text wrapped
// onto lines indented further; a blank line ends a block of options.
std::vector<Option> options_of(const std::string& page, const std::string& help) {
  static const std::regex option_line(
      R"(^  (?:-([a-zA-Z]) \[ --([a-z0-9-]+) \]|--([a-z0-9-]+))( arg)?(?: \(=([^)]*)\))?(?:\s+(.*))?$)");
  std::vector<Option> options;
  bool in_block = false;
  for (const std::string& line : lines_of(help)) {
    std::smatch m;
    if (std::regex_match(line, m, option_line)) {
      Option o;
      o.page = page;
      o.short_name = m[1].matched ? "-" + m[1].str() : "";
      o.name = "--" + (m[2].matched ? m[2].str() : m[3].str());
      o.takes_value = m[4].matched;
      o.has_default = m[5].matched;
      o.default_text = m[5].str();
      o.text = m[6].str();
      options.push_back(o);
      in_block = true;
    } else if (line.empty()) {
      in_block = false;
    } else if (in_block && line.rfind("   ", 0) == 0) {
      options.back().text += " " + line.substr(line.find_first_not_of(' '));
    }
  }
  for (Option& o : options) o.text = std::regex_replace(o.text, std::regex(" +"), " ");  // boost pads wrapped lines
  for (Option& o : options)
    while (!o.text.empty() && o.text.back() == ' ') o.text.pop_back();
  return options;
}

// The lines of the page's last "Examples:" block; empty when the page does not end with one.
std::vector<std::string> final_examples(const std::string& help) {
  const std::vector<std::string> lines = lines_of(help);
  size_t at = lines.size();
  for (size_t i = 0; i < lines.size(); ++i)
    if (lines[i] == "Examples:") at = i;
  std::vector<std::string> examples;
  for (size_t i = at + 1; i < lines.size(); ++i) {
    if (lines[i].empty()) continue;
    if (lines[i].rfind("  stylerf ", 0) != 0) return {};  // something else after the examples
    examples.push_back(lines[i].substr(2));
  }
  return examples;
}

// Significant digits of a decimal number's text ("0.0299999993" -> 9); -1 when it is not a number.
int significant_digits(const std::string& s) {
  char* end = nullptr;
  std::strtod(s.c_str(), &end);
  if (s.empty() || *end != '\0') return -1;
  const std::string mantissa = s.substr(0, s.find_first_of("eE"));
  std::string digits;
  for (char c : mantissa)
    if (c >= '0' && c <= '9') digits += c;
  const size_t first = digits.find_first_not_of('0');
  if (first == std::string::npos) return 1;
  digits = digits.substr(first);
  if (mantissa.find('.') == std::string::npos) digits = digits.substr(0, digits.find_last_not_of('0') + 1);
  return int(digits.size());
}

// The commands `stylerf help` lists: "  name   summary" lines under the group headings.
std::vector<std::string> listed_commands(const std::string& help) {
  static const std::regex command_line(R"(^  ([a-z][a-z-]*)  +\S.*$)");
  std::vector<std::string> names;
  for (const std::string& line : lines_of(help)) {
    std::smatch m;
    if (std::regex_match(line, m, command_line)) names.push_back(m[1].str());
  }
  return names;
}

// `stylerf eval --help`'s subcommands: the lines after "subcommands:" up to a blank line.
std::vector<std::string> listed_subcommands(const std::string& help) {
  std::vector<std::string> names;
  bool on = false;
  for (const std::string& line : lines_of(help)) {
    if (line == "subcommands:") on = true;
    else if (line.empty()) on = false;
    else if (on) names.push_back(line.substr(2, line.find(' ', 2) - 2));
  }
  return names;
}

// Every page, walked once per process: page name ("train-style", "eval table") -> its --help text.
const std::map<std::string, std::string>& pages() {
  static const std::map<std::string, std::string> all = [] {
    std::map<std::string, std::string> p;
    const CliRun help = run_cli("help");
    REQUIRE(help.code == 0);
    for (const std::string& c : listed_commands(help.output)) {
      // A command that keeps options behind --help-all (train-style) is checked with all of them.
      const CliRun r = run_cli(c + " --help");
      INFO("stylerf " << c << " --help:\n" << r.output);
      REQUIRE(r.code == 0);
      p[c] = r.output;
      if (has(r.output, "--help-all")) {
        const CliRun all_options = run_cli(c + " --help-all");
        REQUIRE(all_options.code == 0);
        p[c] = all_options.output;
      }
    }
    for (const std::string& s : listed_subcommands(p.at("eval"))) {
      const CliRun r = run_cli("eval " + s + " --help");
      INFO("stylerf eval " << s << " --help:\n" << r.output);
      REQUIRE(r.code == 0);
      p["eval " + s] = r.output;
    }
    return p;
  }();
  return all;
}

std::vector<Option> all_options() {
  std::vector<Option> all;
  for (const auto& [page, text] : pages())
    for (const Option& o : options_of(page, text)) all.push_back(o);
  return all;
}

}  // namespace

TEST_CASE("stylerf help: commands grouped by workflow, each with a one-line example") {
  const CliRun r = run_cli("help");
  REQUIRE(r.code == 0);
  size_t last = 0;
  for (const char* group : {"get a scene:", "train:", "stylise and render:", "evaluate:", "tools:"}) {
    const size_t at = r.output.find(std::string("\n") + group + "\n");
    INFO(group);
    REQUIRE(at != std::string::npos);
    CHECK(at > last);  // in workflow order
    last = at;
  }
  const std::vector<std::string> lines = lines_of(r.output);
  const std::vector<std::string> names = listed_commands(r.output);
  CHECK(names.size() >= 15);
  for (size_t i = 0; i + 1 < lines.size(); ++i) {
    const std::vector<std::string> one = listed_commands(lines[i]);
    if (one.empty()) continue;
    INFO(lines[i]);
    const std::string example = lines[i + 1].substr(lines[i + 1].find_first_not_of(' '));
    CHECK(example.rfind("stylerf " + one.front(), 0) == 0);
  }
  CHECK(final_examples(r.output).size() >= 1);
  // bench's summary names every benchmark its --help lists.
  for (const char* b : {"gemm", "conv", "ops", "field", "density", "targets", "patch", "dst", "render", "decoder-step"})
    CHECK(has(r.output.substr(r.output.find("  bench ")), b));
}

TEST_CASE("stylerf --version: version, commit and the OpenCL devices") {
  const CliRun r = run_cli("--version");
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(std::regex_search(r.output, std::regex(R"(^stylerf \d+\.\d+\.\d+ \(commit ([0-9a-f]{7,}|unknown)\)\n)")));
  CHECK(has(r.output, "\nOpenCL devices:\n"));
}

TEST_CASE("every page answers --help with status 0 and ends with one or two examples of itself") {
  CHECK(pages().size() >= 18);
  CHECK(pages().count("devices"));
  CHECK(pages().count("eval style"));
  for (const auto& [page, text] : pages()) {
    INFO("stylerf " << page << " --help:\n" << text);
    const std::vector<std::string> examples = final_examples(text);
    CHECK(!examples.empty());
    CHECK(examples.size() <= 2);
    for (const std::string& e : examples) CHECK(e.rfind("stylerf " + page.substr(0, page.find(' ')), 0) == 0);
    if (page != "eval") CHECK(!options_of(page, text).empty());  // eval's page lists its subcommands
  }
}

TEST_CASE("every default is printed as a user would type it") {
  CHECK(significant_digits("0.0299999993") == 9);  // boost's text for 0.03f, the rule's own check
  CHECK(significant_digits("0.03") == 1);
  CHECK(significant_digits("4096") == 4);
  CHECK(significant_digits("100000") == 1);
  CHECK(significant_digits("alex") == -1);
  for (const Option& o : all_options()) {
    if (!o.has_default) continue;
    INFO("stylerf " << o.page << ": " << o.name << " (=" << o.default_text << ")");
    CHECK(!o.default_text.empty());
    CHECK(significant_digits(o.default_text) <= 6);  // -1 for words; 0.0299999993 has 9
  }
}

TEST_CASE("one meaning per name: the names the grammar fixes mean the same on every page") {
  std::map<std::string, std::vector<Option>> by_name;
  for (const Option& o : all_options()) by_name[o.name].push_back(o);
  REQUIRE(by_name.count("--output"));
  auto each = [&](const std::string& name, const std::function<bool(const Option&)>& ok, const std::string& rule) {
    for (const Option& o : by_name[name]) {
      INFO("stylerf " << o.page << " " << name << ": \"" << o.text << "\" must be " << rule);
      CHECK(ok(o));
    }
  };
  // A name takes a value everywhere or nowhere.
  for (const auto& [name, uses] : by_name)
    for (const Option& o : uses) {
      INFO(name << " on " << o.page << " and " << uses.front().page);
      CHECK(o.takes_value == uses.front().takes_value);
    }
  // Every output is -o/--output, and -o is nothing else.
  for (const Option& o : all_options()) {
    INFO("stylerf " << o.page << " " << o.name);
    CHECK((o.short_name == "-o") == (o.name == "--output"));
    CHECK(o.name != "--out");
    CHECK(!has(o.name, "budget"));  // budgets are --minutes
  }
  each("--views", [](const Option& o) { return has(o.text, "test") && has(o.text, "path"); }, "a selection, test|path");
  each("--max-views", [](const Option& o) { return o.takes_value && has(o.text, "evenly spaced"); }, "a count");
  each("--supersample", [](const Option& o) { return has(o.text, "per feature-map block"); },
       "content rays per feature-map block");
  each("--timing", [](const Option& o) { return !o.takes_value && has(o.text, "per-kernel times"); }, "kernel times");
  each("--minutes", [](const Option& o) { return has(o.text, "minutes"); }, "in minutes");
  each("--scored-frames", [](const Option& o) { return has(o.text, "frames compared"); }, "a count of scored frames");
  each("--device", [&](const Option& o) { return o.text == by_name["--device"].front().text; },
       "the same text on every page");
  each("--device", [](const Option& o) { return has(o.text, "(default: "); }, "with its default");
  CHECK(by_name["--views"].size() >= 2);
  CHECK(by_name["--max-views"].size() >= 3);
  CHECK(by_name["--timing"].size() >= 4);
  CHECK(by_name["--minutes"].size() >= 4);
  CHECK(by_name["--supersample"].size() >= 4);
}

TEST_CASE("old spellings keep working, each with a one-line notice") {
  CliRun r = run_cli("adain --profile --help");
  CHECK(r.code == 0);
  CHECK(has(r.output, "--profile is now --timing"));
  r = run_cli("eval-style --help");
  CHECK(r.code == 0);
  CHECK(has(r.output, "eval-style is now `eval style`"));
  CHECK(has(r.output, "stylerf eval style --ckpt"));
  r = run_cli("bench density --budget 60");  // seconds read as minutes would be 60x longer: refused instead
  CHECK(r.code == 1);
  CHECK(has(r.output, "--budget (seconds) is now --minutes"));
}
