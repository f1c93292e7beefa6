// Reading takes and recorded streams (take_reader.h): line by line (the file read in large
// blocks), each line parsed on its own, every problem an error naming the file, the line and the
// fix; the takes of a folder with their state (an flock held by the writer tells a live take
// from an interrupted one).
//
// A "skeletons" line exactly as encode_skeletons writes it (its key order, no spaces, numbers
// with a fraction, plain ASCII names equal to the take's) is read by a hand-written scanner
// (SkeletonsScanner, ~20x faster than nlohmann::json); any other line, or one it does not fully
// recognise, is parsed with nlohmann::json, so every error and every odd-but-valid line reads as
// before. Both give the same TakeData (take_test checks it).
#include "runtime/out/take_reader.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <string_view>
#include <system_error>
#include <thread>

#include "runtime/core/text_scan.h"
#include "runtime/msg/stream_json.h"
#include "runtime/out/take_writer.h"

namespace mocap::out {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::uintmax_t kMaxTakeJson_bytes = 64 << 20;
constexpr const char* kStreamHint =
    "give a take folder recorded by mocapd (take.json + skeletons.ndjson) or a stream saved from "
    "the box (nc BOX 9870 > FILE.ndjson)";

Error line_error(const fs::path& file, int line, const std::string& what) {
  return Error(ErrorCode::kParse, file.string() + ":" + std::to_string(line) + ": " + what);
}

bool blank(std::string_view line) {
  return std::all_of(line.begin(), line.end(),
                     [](char c) { return c == ' ' || c == '\t' || c == '\r'; });
}

std::string str_field(const json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
}

std::int64_t int_field(const json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_number_integer() ? it->get<std::int64_t>() : 0;
}

// A coordinate or a confidence: a number, or null (never seen) as NaN; false otherwise.
bool number_or_null(const json& j, const char* key, double& out) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) {
    out = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  if (!it->is_number()) return false;
  out = it->get<double>();
  return true;
}

// A joint's position and confidence as both parsers store them (NaN or null: not seen).
void set_joint(TakePerson& p, std::size_t j, double x, double y, double z, double c) {
  const bool seen = std::isfinite(x) && std::isfinite(y) && std::isfinite(z) && std::isfinite(c);
  p.joints_m[j] = Eigen::Vector3d(x, y, z);
  p.confidence[j] = seen ? static_cast<float>(std::clamp(c, 0.0, 1.0)) : 0.f;
}

// A foot point read back; false for a contact state the stream does not write.
bool set_foot(FootPoint& f, double x, double y, double z, std::string_view contact) {
  f.X_m = Eigen::Vector3d(x, y, z);
  f.valid = f.X_m.allFinite();
  for (const FootContact c : {FootContact::kUnknown, FootContact::kFree, FootContact::kPlanted}) {
    if (contact == to_string(c)) {
      f.contact = c;
      return true;
    }
  }
  return false;
}

// The fast path: a "skeletons" line in encode_skeletons' exact layout. Every scan returns
// false (and the line goes to nlohmann::json) where the layout differs in any way.
class SkeletonsScanner {
 public:
  explicit SkeletonsScanner(std::string_view line)
      : p_(line.data()), end_(line.data() + line.size()) {}
  // A frame of a take whose topology and joint names are known: false unless the whole line
  // is in the layout with this topology and these names (then `frame` is what the slow path
  // gives).
  bool frame(const std::string& topology, const std::vector<std::string>& names, TakeFrame& out);

 private:
  bool lit(std::string_view s);
  bool plain_string(std::string_view& out);
  template <typename T>
  bool integer(T& out);
  bool number_or_null(double& out);
  bool person(const std::vector<std::string>& names, TakePerson& out);
  bool joint(const std::string& name, std::size_t j, TakePerson& out);
  bool rotation();
  bool foot(std::size_t k, FootPoint& out);

  const char* p_;
  const char* end_;
};

bool SkeletonsScanner::lit(std::string_view s) {
  if (static_cast<std::size_t>(end_ - p_) < s.size() || std::memcmp(p_, s.data(), s.size()) != 0)
    return false;
  p_ += s.size();
  return true;
}

// "..." of printable ASCII without escapes (anything else goes the slow way).
bool SkeletonsScanner::plain_string(std::string_view& out) {
  if (p_ == end_ || *p_ != '"') return false;
  const char* begin = ++p_;
  while (p_ != end_ && *p_ != '"') {
    if (*p_ < 0x20 || *p_ > 0x7e || *p_ == '\\') return false;
    ++p_;
  }
  if (p_ == end_) return false;
  out = std::string_view(begin, static_cast<std::size_t>(p_ - begin));
  ++p_;
  return true;
}

bool is_digit(char c) { return c >= '0' && c <= '9'; }

// A JSON integer (-?(0|[1-9][0-9]*)) that fits T.
template <typename T>
bool SkeletonsScanner::integer(T& out) {
  const char* q = p_ != end_ && *p_ == '-' ? p_ + 1 : p_;
  if (q == end_ || !is_digit(*q) || (*q == '0' && q + 1 != end_ && is_digit(q[1]))) return false;
  const auto [ptr, ec] = std::from_chars(p_, end_, out);
  if (ec != std::errc() || (ptr != end_ && (*ptr == '.' || *ptr == 'e' || *ptr == 'E')))
    return false;
  p_ = ptr;
  return true;
}

// The decimal digits..end as the double nearest N / 10^k (N the digits, k the fraction's
// length): exact for N < 2^53 and k <= 22, where both are exact doubles and the division rounds
// once, as strtod would; longer numbers go to from_chars.
bool parse_decimal(const char* begin, const char* end, bool negative, std::size_t fraction,
                   double& out) {
  static constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                      1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                      1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  if (end - begin > 16 || fraction > 22) return false;  // 15 digits and the point
  std::uint64_t n = 0;
  for (const char* q = begin; q != end; ++q) {
    if (*q != '.') n = n * 10 + static_cast<std::uint64_t>(*q - '0');
  }
  const double v = static_cast<double>(n) / kPow10[fraction];
  out = negative ? -v : v;
  return true;
}

// null (NaN), or a number with a fraction and no exponent (-?(0|[1-9][0-9]*)\.[0-9]+): the
// fixed decimals the box writes, rounded as nlohmann's strtod does.
bool SkeletonsScanner::number_or_null(double& out) {
  if (lit("null")) {
    out = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  const char* digits = p_ != end_ && *p_ == '-' ? p_ + 1 : p_;
  const char* q = digits;
  if (q == end_ || !is_digit(*q)) return false;
  if (*q == '0') {
    ++q;
  } else {
    while (q != end_ && is_digit(*q)) ++q;
  }
  if (q == end_ || *q != '.' || q + 1 == end_ || !is_digit(q[1])) return false;
  const char* fraction = ++q;
  while (q != end_ && is_digit(*q)) ++q;
  const auto k = static_cast<std::size_t>(q - fraction);
  if (!parse_decimal(digits, q, digits != p_, k, out)) {
    const auto [ptr, ec] = std::from_chars(p_, q, out);
    if (ec != std::errc() || ptr != q) return false;
  }
  p_ = q;
  return true;
}

// ,"rotation":[w,x,y,z] (read and dropped, as the slow path ignores it).
bool SkeletonsScanner::rotation() {
  double v = 0;
  return lit(",\"rotation\":[") && number_or_null(v) && lit(",") && number_or_null(v) && lit(",") &&
         number_or_null(v) && lit(",") && number_or_null(v) && lit("]");
}

bool SkeletonsScanner::joint(const std::string& name, std::size_t j, TakePerson& out) {
  std::string_view n;
  double x = 0, y = 0, z = 0, c = 0;
  if (!lit("{\"name\":") || !plain_string(n) || n != name || !lit(",\"x\":") ||
      !number_or_null(x) || !lit(",\"y\":") || !number_or_null(y) || !lit(",\"z\":") ||
      !number_or_null(z) || !lit(",\"confidence\":") || !number_or_null(c)) {
    return false;
  }
  if (p_ != end_ && *p_ == ',' && !rotation()) return false;
  if (!lit("}")) return false;
  set_joint(out, j, x, y, z, c);
  return true;
}

bool SkeletonsScanner::person(const std::vector<std::string>& names, TakePerson& out) {
  if (!lit("{\"id\":") || !integer(out.id) || !lit(",\"joints\":[")) return false;
  out.joints_m.resize(names.size());
  out.confidence.resize(names.size());
  for (std::size_t j = 0; j < names.size(); ++j) {
    if (j > 0 && !lit(",")) return false;
    if (!joint(names[j], j, out)) return false;
  }
  if (!lit("]")) return false;
  if (lit(",\"feet\":[")) {
    for (std::size_t k = 0; k < kFootPoints; ++k) {
      if (k > 0 && !lit(",")) return false;
      if (!foot(k, out.feet[k])) return false;
    }
    if (!lit("]")) return false;
  }
  return lit("}");
}

// {"name":"l_heel","x":..,"y":..,"z":..,"contact":"planted","views":3}
bool SkeletonsScanner::foot(std::size_t k, FootPoint& out) {
  std::string_view n, contact;
  double x = 0, y = 0, z = 0;
  if (!lit("{\"name\":") || !plain_string(n) || n != kFootPointNames[k] || !lit(",\"x\":") ||
      !number_or_null(x) || !lit(",\"y\":") || !number_or_null(y) || !lit(",\"z\":") ||
      !number_or_null(z) || !lit(",\"contact\":") || !plain_string(contact) ||
      !lit(",\"views\":") || !integer(out.views_used) || !lit("}")) {
    return false;
  }
  return set_foot(out, x, y, z, contact);
}

bool SkeletonsScanner::frame(const std::string& topology, const std::vector<std::string>& names,
                             TakeFrame& out) {
  std::string_view t;
  if (!lit("{\"schema\":\"mocap-box.stream/1\",\"type\":\"skeletons\",\"frame_id\":") ||
      !integer(out.frame_id) || !lit(",\"capture_monotonic_ns\":") ||
      !integer(out.capture_monotonic_ns) || !lit(",\"capture_unix_ns\":") ||
      !integer(out.capture_unix_ns) || !lit(",\"topology\":") || !plain_string(t) ||
      t != topology || !lit(",\"persons\":[")) {
    return false;
  }
  out.persons.clear();
  if (lit("]}")) return p_ == end_;
  do {
    out.persons.emplace_back();
    if (!person(names, out.persons.back())) return false;
  } while (lit(","));
  return lit("]}") && p_ == end_;
}

// The "skeletons" messages of one stream file, line by line, into a TakeData.
class StreamParser {
 public:
  StreamParser(fs::path file, TakeData& data) : file_(std::move(file)), data_(data) {}
  Status add_line(std::string_view line, int line_no);
  // Once the first frame fixed the topology and the names, any thread may scan a line on the
  // fast path (no state is touched); add_frame then keeps the frames in file order.
  bool ready() const { return names_known_ && !data_.topology.empty(); }
  bool scan(std::string_view line, TakeFrame& frame) const {
    return SkeletonsScanner(line).frame(data_.topology, data_.joint_names, frame);
  }
  void add_frame(TakeFrame&& frame) { data_.frames.push_back(std::move(frame)); }
  Status check_partial_line(std::string_view line, int line_no) const;

 private:
  bool add_fast(std::string_view line);
  Status check_schema(const json& msg, int line_no) const;
  Status add_skeletons(const json& msg, int line_no);
  Status add_person(const json& person, int line_no, TakeFrame& frame);
  Status add_joint(const json& joint, std::size_t j, int line_no, TakePerson& person);
  Status add_feet(const json& person, int line_no, TakePerson& p);
  Status check_topology(const json& msg, int line_no);

  fs::path file_;
  TakeData& data_;
  bool names_known_ = false;
  int topology_line_ = 0;
};

// The fast path, once the first frame (by the slow path) fixed the topology and the names.
bool StreamParser::add_fast(std::string_view line) {
  if (!names_known_ || data_.topology.empty()) return false;
  TakeFrame frame;
  if (!SkeletonsScanner(line).frame(data_.topology, data_.joint_names, frame)) return false;
  data_.frames.push_back(std::move(frame));
  return true;
}

Status StreamParser::add_line(std::string_view line, int line_no) {
  if (add_fast(line)) return {};
  const json msg = json::parse(line.begin(), line.end(), nullptr, false);
  if (msg.is_discarded() || !msg.is_object()) {
    if (line_no == 1) {
      return line_error(file_, 1,
                        std::string("not a mocap-box take or stream (the line is not a JSON "
                                    "object): ") +
                            kStreamHint);
    }
    return line_error(file_, line_no,
                      "malformed line (not a JSON object): the file is damaged; keep the lines "
                      "before it (head -n " +
                          std::to_string(line_no - 1) + ") or record the take again");
  }
  if (Status s = check_schema(msg, line_no); !s.ok()) return s;
  if (str_field(msg, "type") != "skeletons") {
    ++data_.skipped_messages;  // detections, or a type a newer box added
    return {};
  }
  return add_skeletons(msg, line_no);
}

Status StreamParser::check_schema(const json& msg, int line_no) const {
  const std::string schema = str_field(msg, "schema");
  if (schema == kStreamSchema) return {};
  if (schema.rfind("mocap-box.stream/", 0) == 0) {
    return line_error(file_, line_no,
                      "stream schema '" + schema + "' is newer than this program reads (" +
                          kStreamSchema + "): update mocap");
  }
  return line_error(file_, line_no,
                    std::string("not a mocap-box take or stream (no \"schema\": \"") +
                        kStreamSchema + "\"): " + kStreamHint);
}

// A last line without its newline: a crash's cut-off line, unless the whole file is that one
// line of something else (a foreign file without a trailing newline).
Status StreamParser::check_partial_line(std::string_view line, int line_no) const {
  if (line_no > 1) return {};
  const std::string_view head = line.substr(0, 80);
  if (!head.empty() && head.front() == '{' && head.find("mocap-box.stream/") != std::string::npos)
    return {};
  return line_error(file_, 1,
                    std::string("not a mocap-box take or stream (one line without a newline "
                                "that is not a stream message): ") +
                        kStreamHint);
}

Status StreamParser::check_topology(const json& msg, int line_no) {
  const std::string topology = str_field(msg, "topology");
  if (topology.empty()) {
    return line_error(file_, line_no,
                      "skeletons message without \"topology\": the file is "
                      "damaged or not written by mocap-box");
  }
  if (data_.topology.empty()) {
    data_.topology = topology;
    topology_line_ = line_no;
  } else if (topology != data_.topology) {
    return line_error(file_, line_no,
                      "the topology changes from '" + data_.topology + "' (line " +
                          std::to_string(topology_line_) + ") to '" + topology +
                          "': a take has one skeleton; split the file where it changes");
  }
  return {};
}

Status StreamParser::add_skeletons(const json& msg, int line_no) {
  if (Status s = check_topology(msg, line_no); !s.ok()) return s;
  const auto fid = msg.find("frame_id");
  const auto mono = msg.find("capture_monotonic_ns");
  const auto persons = msg.find("persons");
  if (fid == msg.end() || !fid->is_number_unsigned() || mono == msg.end() ||
      !mono->is_number_integer() || persons == msg.end() || !persons->is_array()) {
    return line_error(file_, line_no,
                      "skeletons message without an integer \"frame_id\", an integer "
                      "\"capture_monotonic_ns\" or a \"persons\" array: the file is damaged");
  }
  TakeFrame frame;
  frame.frame_id = fid->get<std::uint64_t>();
  frame.capture_monotonic_ns = mono->get<std::int64_t>();
  frame.capture_unix_ns = int_field(msg, "capture_unix_ns");
  frame.persons.reserve(persons->size());
  for (const json& person : *persons) {
    if (Status s = add_person(person, line_no, frame); !s.ok()) return s;
  }
  data_.frames.push_back(std::move(frame));
  return {};
}

Status StreamParser::add_person(const json& person, int line_no, TakeFrame& frame) {
  const std::string where = "person " + std::to_string(frame.persons.size());
  if (!person.is_object() || !person.contains("id") || !person["id"].is_number_integer() ||
      !person.contains("joints") || !person["joints"].is_array()) {
    return line_error(file_, line_no,
                      where +
                          " has no integer \"id\" or no \"joints\" array: the file is "
                          "damaged");
  }
  const json& joints = person["joints"];
  if (!names_known_) {
    data_.joint_names.assign(joints.size(), std::string());
  } else if (joints.size() != data_.joint_names.size()) {
    return line_error(file_, line_no,
                      where + " has " + std::to_string(joints.size()) + " joints, earlier ones " +
                          std::to_string(data_.joint_names.size()) +
                          ": a take has one skeleton; split the file where it changes");
  }
  TakePerson p;
  p.id = person["id"].get<int>();
  p.joints_m.resize(joints.size());
  p.confidence.resize(joints.size());
  for (std::size_t j = 0; j < joints.size(); ++j) {
    if (Status s = add_joint(joints[j], j, line_no, p); !s.ok()) return s;
  }
  names_known_ = true;
  if (Status s = add_feet(person, line_no, p); !s.ok()) return s;
  frame.persons.push_back(std::move(p));
  return {};
}

Status StreamParser::add_feet(const json& person, int line_no, TakePerson& p) {
  const auto it = person.find("feet");
  if (it == person.end()) return {};
  const std::string where = "person " + std::to_string(p.id) + " \"feet\"";
  if (!it->is_array() || it->size() != kFootPoints) {
    return line_error(file_, line_no,
                      where + ": needs an array of " + std::to_string(kFootPoints) +
                          " foot points: the file is damaged");
  }
  for (std::size_t k = 0; k < kFootPoints; ++k) {
    const json& f = (*it)[k];
    double x = 0, y = 0, z = 0;
    const bool ok =
        f.is_object() && str_field(f, "name") == kFootPointNames[k] && number_or_null(f, "x", x) &&
        number_or_null(f, "y", y) && number_or_null(f, "z", z) && f.contains("views") &&
        f["views"].is_number_integer() && set_foot(p.feet[k], x, y, z, str_field(f, "contact"));
    if (!ok) {
      return line_error(file_, line_no,
                        where + " " + std::to_string(k) + ": needs \"name\" " + kFootPointNames[k] +
                            ", numbers (or null) \"x\", \"y\", \"z\", a \"contact\" "
                            "(unknown, free, planted) and \"views\": the file is damaged");
    }
    p.feet[k].views_used = f["views"].get<int>();
  }
  return {};
}

Status StreamParser::add_joint(const json& joint, std::size_t j, int line_no, TakePerson& p) {
  const std::string where = "person " + std::to_string(p.id) + " joint " + std::to_string(j);
  double x = 0, y = 0, z = 0, c = 0;
  const std::string name = joint.is_object() ? str_field(joint, "name") : std::string();
  if (name.empty() || !number_or_null(joint, "x", x) || !number_or_null(joint, "y", y) ||
      !number_or_null(joint, "z", z) || !number_or_null(joint, "confidence", c)) {
    return line_error(file_, line_no,
                      where +
                          ": needs a \"name\" and numbers (or null) \"x\", \"y\", \"z\", "
                          "\"confidence\": the file is damaged");
  }
  std::string& known = data_.joint_names[j];
  if (!names_known_) {
    known = name;
  } else if (name != known) {
    return line_error(file_, line_no,
                      where + " is '" + name + "', earlier '" + known +
                          "': the joint names change; a take has one skeleton, split the file");
  }
  set_joint(p, j, x, y, z, c);
  return {};
}

// The lines of a file, read in large blocks (a line may span blocks).
class LineReader {
 public:
  explicit LineReader(int fd) : fd_(fd), buf_(kBlock) {}
  // The next line without its newline (valid until the next call); `complete`: a newline ended
  // it. False at the end of the file or on a read error (failed()).
  bool next(std::string_view& line, bool& complete);
  bool failed() const { return failed_; }

 private:
  static constexpr std::size_t kBlock = 8 << 20;
  void fill();
  int fd_;
  std::vector<char> buf_;
  std::size_t begin_ = 0, end_ = 0;  // the unread bytes of buf_
  bool eof_ = false, failed_ = false;
};

bool LineReader::next(std::string_view& line, bool& complete) {
  std::size_t scanned = begin_;  // no newline in [begin_, scanned)
  while (true) {
    const char* b = buf_.data();
    const void* nl = std::memchr(b + scanned, '\n', end_ - scanned);
    if (nl != nullptr) {
      const auto at = static_cast<std::size_t>(static_cast<const char*>(nl) - b);
      line = std::string_view(b + begin_, at - begin_);
      begin_ = at + 1;
      complete = true;
      return true;
    }
    if (failed_ || (eof_ && begin_ == end_)) return false;
    if (eof_) {
      line = std::string_view(b + begin_, end_ - begin_);
      begin_ = end_;
      complete = false;
      return true;
    }
    scanned = end_ - begin_;
    fill();  // moves the unread bytes to the front
  }
}

void LineReader::fill() {
  std::memmove(buf_.data(), buf_.data() + begin_, end_ - begin_);
  end_ -= begin_;
  begin_ = 0;
  if (end_ == buf_.size()) buf_.resize(buf_.size() * 2);  // a line longer than a block
  while (true) {
    const ssize_t n = ::read(fd_, buf_.data() + end_, buf_.size() - end_);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      failed_ = n < 0;
      eof_ = true;
    } else {
      end_ += static_cast<std::size_t>(n);
    }
    return;
  }
}

// The lines of a text in memory, as LineReader gives a file's (parse_stream_text).
class MemoryLineReader {
 public:
  explicit MemoryLineReader(std::string_view text) : rest_(text) {}
  bool next(std::string_view& line, bool& complete) {
    if (rest_.empty()) return false;
    const std::size_t nl = rest_.find('\n');
    complete = nl != std::string_view::npos;
    line = rest_.substr(0, nl);
    rest_ = complete ? rest_.substr(nl + 1) : std::string_view();
    return true;
  }
  bool failed() const { return false; }

 private:
  std::string_view rest_;
};

// Complete lines waiting to be parsed, copied out of the reader's buffer.
struct LineBatch {
  static constexpr std::size_t kLines = 4096;
  std::string bytes;
  std::vector<std::size_t> ends;
  std::vector<int> numbers;
  std::string_view line(std::size_t k) const {
    const std::size_t begin = k == 0 ? 0 : ends[k - 1];
    return std::string_view(bytes).substr(begin, ends[k] - begin);
  }
  void add(std::string_view line, int number) {
    bytes.append(line);
    ends.push_back(bytes.size());
    numbers.push_back(number);
  }
  void clear() {
    bytes.clear();
    ends.clear();
    numbers.clear();
  }
};

// The batch's lines in order: the fast path scanned on every core (the bulk of a take's
// reading), each line it does not recognise through the full parser, in file order.
Status flush_batch(const LineBatch& batch, StreamParser& parser) {
  const std::size_t n = batch.ends.size();
  std::vector<TakeFrame> frames(n);
  std::vector<char> fast(n, 0);
  const std::size_t workers = std::clamp<std::size_t>(std::thread::hardware_concurrency(), 1, 8);
  auto work = [&](std::size_t w) {
    for (std::size_t k = w; k < n; k += workers) fast[k] = parser.scan(batch.line(k), frames[k]);
  };
  std::vector<std::thread> threads;
  for (std::size_t w = 1; w < workers && n > 64; ++w) threads.emplace_back(work, w);
  if (threads.empty()) {
    for (std::size_t k = 0; k < n; ++k) fast[k] = parser.scan(batch.line(k), frames[k]);
  } else {
    work(0);
  }
  for (std::thread& t : threads) t.join();
  for (std::size_t k = 0; k < n; ++k) {
    if (fast[k]) {
      parser.add_frame(std::move(frames[k]));
    } else if (Status s = parser.add_line(batch.line(k), batch.numbers[k]); !s.ok()) {
      return s;
    }
  }
  return {};
}

template <typename Reader>
Status read_lines(Reader& in, StreamParser& parser, TakeData& data, int& lines) {
  std::string_view line;
  bool complete = false;
  LineBatch batch;
  while (in.next(line, complete)) {
    ++lines;
    if (!complete) {  // no newline after it: cut off by a crash
      if (Status s = flush_batch(batch, parser); !s.ok()) return s;
      batch.clear();
      if (blank(line)) break;
      if (Status s = parser.check_partial_line(line, lines); !s.ok()) return s;
      data.partial_lines = 1;
      break;
    }
    if (blank(line)) continue;
    if (!parser.ready()) {  // the first frame fixes the topology and names: on its own
      if (Status s = parser.add_line(line, lines); !s.ok()) return s;
      continue;
    }
    batch.add(line, lines);
    if (batch.ends.size() == LineBatch::kLines) {
      if (Status s = flush_batch(batch, parser); !s.ok()) return s;
      batch.clear();
    }
  }
  return flush_batch(batch, parser);
}

Error no_frames_error(const fs::path& file, const TakeData& data) {
  if (data.skipped_messages > 0) {
    return Error(ErrorCode::kInvalidArgument,
                 file.string() + ": the take has no skeleton frames (" +
                     std::to_string(data.skipped_messages) +
                     " detections messages): was the box calibrated while recording? Calibrate "
                     "it (the web page's \"Calibrate with a board\", mocap calibrate board or "
                     "mocap calibrate people) and record again");
  }
  return Error(ErrorCode::kInvalidArgument,
               file.string() + ": the take has no skeleton frames" +
                   (data.partial_lines > 0 ? " (only an incomplete line)" : "") +
                   ": was the box calibrated while recording?");
}

// What every stream needs once its lines are read: a line at all, and a skeleton frame.
Result<TakeData> finish_stream(const fs::path& ndjson, TakeData data, int lines) {
  if (lines == 0) {
    return Error(ErrorCode::kInvalidArgument,
                 ndjson.string() +
                     ": empty: the take recorded nothing (stopped right away, or "
                     "the box sent no frame)");
  }
  if (data.frames.empty()) return no_frames_error(ndjson, data);
  return data;
}

// Runs f over the file's bytes in blocks; false with errno set when reading fails.
template <typename F>
bool for_each_block(const fs::path& file, F&& f) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  std::vector<char> buf(1 << 20);
  std::uint64_t offset = 0;
  while (true) {
    const ssize_t n = ::read(fd, buf.data(), buf.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int e = errno;
      ::close(fd);
      errno = e;
      return false;
    }
    if (n == 0) break;
    f(buf.data(), static_cast<std::size_t>(n), offset);
    offset += static_cast<std::uint64_t>(n);
  }
  ::close(fd);
  return true;
}

std::uint64_t count_lines(const fs::path& file) {
  std::uint64_t lines = 0;
  (void)for_each_block(file, [&](const char* p, std::size_t n, std::uint64_t) {
    lines += static_cast<std::uint64_t>(std::count(p, p + n, '\n'));
  });
  return lines;
}

// count_lines of an interrupted take's stream, counted once per version of the file (its
// inode, size and modification time): GET /takes lists the takes on the server thread, and a
// 512 MiB take took 125 ms to count every time.
std::uint64_t count_lines_once(const fs::path& file) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) return 0;
  struct Seen {
    dev_t dev;
    ino_t ino;
    off_t size;
    std::int64_t mtime_ns;
    std::uint64_t lines;
  };
  static std::mutex mu;
  static std::vector<Seen> seen;  // the latest 64 files counted
  const std::int64_t mtime_ns = std::int64_t{st.st_mtim.tv_sec} * 1000000000 + st.st_mtim.tv_nsec;
  {
    std::lock_guard lock(mu);
    for (const Seen& s : seen) {
      if (s.dev == st.st_dev && s.ino == st.st_ino && s.size == st.st_size &&
          s.mtime_ns == mtime_ns) {
        return s.lines;
      }
    }
  }
  const std::uint64_t lines = count_lines(file);
  std::lock_guard lock(mu);
  if (seen.size() >= 64) seen.erase(seen.begin());
  seen.push_back({st.st_dev, st.st_ino, st.st_size, mtime_ns, lines});
  return lines;
}

// True when a writer holds the take's lock (TakeWriter: flock on skeletons.ndjson).
bool being_recorded(const fs::path& stream) {
  const int fd = ::open(stream.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool locked = ::flock(fd, LOCK_SH | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  ::close(fd);
  return locked;
}

// take.json of a take folder: its JSON, or an error saying why it cannot be used.
Result<json> read_take_json(const fs::path& file) {
  Result<std::string> text = read_text_file(file, kMaxTakeJson_bytes);
  if (!text.ok()) return text.error();
  return parse_take_json(*text, file);
}

TakeInfo describe_take(const fs::path& dir) {
  TakeInfo info;
  info.name = dir.filename().string();
  const fs::path meta = dir / kTakeMetadataFile;
  std::error_code ec;
  if (!fs::exists(meta, ec)) {
    info.status = TakeStatus::kUnreadable;
    info.reason = meta.string() + ": missing: not a take folder (or its start was cut off)";
    return info;
  }
  Result<json> j = read_take_json(meta);
  if (!j.ok()) {
    info.status = TakeStatus::kUnreadable;
    info.reason = j.error().message();
    return info;
  }
  info.metadata = *j;
  info.reason = str_field(*j, "reason");
  const std::string said = str_field(*j, "status");
  const std::optional<TakeStatus> status = parse_written_take_status(said);
  if (!status) {
    info.status = TakeStatus::kUnreadable;
    info.reason = meta.string() + ": status \"" + said +
                  "\" is not recording, complete or stopped: the file was edited or is damaged";
    return info;
  }
  info.status = *status;
  const std::int64_t frames = int_field(*j, "frames");
  info.frames = frames > 0 ? static_cast<std::uint64_t>(frames) : 0;
  info.started_unix_ns = int_field(*j, "started_unix_ns");
  const fs::path stream = dir / kTakeStreamFile;
  if (info.status == TakeStatus::kRecording && !being_recorded(stream)) {
    info.status = TakeStatus::kInterrupted;
    info.reason =
        "the recording was cut off (crash or power loss): readable up to its last "
        "complete line";
    info.frames = count_lines_once(stream);
  }
  return info;
}

// When `dir` holds takes rather than being one: which to give instead.
std::string takes_folder_hint(const fs::path& dir) {
  std::error_code ec;
  fs::directory_iterator it(dir, ec);
  for (; !ec && it != fs::directory_iterator(); it.increment(ec)) {
    std::error_code entry_ec;
    if (fs::exists(it->path() / kTakeStreamFile, entry_ec)) {
      return ": it holds takes; give one of them, e.g. " + it->path().string();
    }
  }
  return {};
}

}  // namespace

Result<json> parse_take_json(std::string_view text, const fs::path& file) {
  const json j = json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) {
    return Error(ErrorCode::kParse, file.string() +
                                        ": not valid JSON: the take's metadata is damaged (move "
                                        "it away to read the stream alone)");
  }
  if (str_field(j, "schema") != kTakeSchema) {
    return Error(ErrorCode::kParse, file.string() + ": not a mocap-box take (no \"schema\": \"" +
                                        kTakeSchema + "\"): " + kStreamHint);
  }
  return j;
}

Result<TakeData> read_stream_file(const fs::path& ndjson) {
  std::error_code ec;
  if (!fs::exists(ndjson, ec)) {
    return Error(ErrorCode::kNotFound, ndjson.string() + ": no such file: check the path");
  }
  if (fs::is_directory(ndjson, ec)) {
    return Error(ErrorCode::kInvalidArgument,
                 ndjson.string() +
                     ": is a folder, not a stream file (a take folder is read as a "
                     "take: mocap export ... --take DIR)");
  }
  const int fd = ::open(ndjson.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    return Error(ErrorCode::kIo, ndjson.string() + ": cannot open: " + std::strerror(errno));
  }
  TakeData data;
  StreamParser parser(ndjson, data);
  LineReader in(fd);
  int lines = 0;
  const Status read = read_lines(in, parser, data, lines);
  ::close(fd);
  if (!read.ok()) return read.error();
  if (in.failed()) {
    return Error(ErrorCode::kIo, ndjson.string() + ": read error after line " +
                                     std::to_string(lines) + ": check the disk");
  }
  return finish_stream(ndjson, std::move(data), lines);
}

Result<TakeData> parse_stream_text(std::string_view text, const fs::path& name) {
  TakeData data;
  StreamParser parser(name, data);
  MemoryLineReader in(text);
  int lines = 0;
  if (Status s = read_lines(in, parser, data, lines); !s.ok()) return s.error();
  return finish_stream(name, std::move(data), lines);
}

Result<TakeData> read_take(const fs::path& take_dir) {
  std::error_code ec;
  if (!fs::exists(take_dir, ec)) {
    return Error(ErrorCode::kNotFound, take_dir.string() +
                                           ": no such take folder: check the path (mocap take "
                                           "list shows the box's takes)");
  }
  if (!fs::is_directory(take_dir, ec)) {
    return Error(ErrorCode::kInvalidArgument,
                 take_dir.string() +
                     ": not a folder: a take is a folder with take.json and "
                     "skeletons.ndjson (a stream file: mocap export ... --stream "
                     "FILE)");
  }
  const fs::path stream = take_dir / kTakeStreamFile;
  if (!fs::exists(stream, ec)) {
    return Error(ErrorCode::kNotFound, stream.string() + ": missing: " + take_dir.string() +
                                           " is not a mocap-box take (a take folder has take.json "
                                           "and skeletons.ndjson)" +
                                           takes_folder_hint(take_dir));
  }
  json metadata;  // null without take.json: the stream alone is still a take
  const fs::path meta = take_dir / kTakeMetadataFile;
  if (fs::exists(meta, ec)) {
    Result<json> j = read_take_json(meta);
    if (!j.ok()) return j.error();
    metadata = std::move(*j);
  }
  Result<TakeData> data = read_stream_file(stream);
  if (!data.ok()) return data.error();
  data->metadata = std::move(metadata);
  return data;
}

Result<std::uint64_t> complete_lines_bytes(const fs::path& ndjson) {
  std::uint64_t end = 0;
  const bool ok = for_each_block(ndjson, [&](const char* p, std::size_t n, std::uint64_t offset) {
    for (std::size_t i = n; i > 0; --i) {
      if (p[i - 1] == '\n') {
        end = offset + i;
        break;
      }
    }
  });
  if (!ok) return Error(ErrorCode::kIo, ndjson.string() + ": cannot read: " + std::strerror(errno));
  return end;
}

Result<std::vector<TakeInfo>> list_takes(const fs::path& takes_dir) {
  std::vector<TakeInfo> takes;
  std::error_code ec;
  if (!fs::exists(takes_dir, ec)) return takes;
  fs::directory_iterator it(takes_dir, ec);
  if (ec) {
    return Error(ErrorCode::kIo, takes_dir.string() + ": cannot list the takes: " + ec.message() +
                                     " (check the takes folder's permissions)");
  }
  for (; !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::error_code entry_ec;
    if (name.empty() || name.front() == '.' || !it->is_directory(entry_ec)) continue;
    takes.push_back(describe_take(it->path()));
  }
  std::sort(takes.begin(), takes.end(), [](const TakeInfo& a, const TakeInfo& b) {
    return a.started_unix_ns != b.started_unix_ns ? a.started_unix_ns < b.started_unix_ns
                                                  : a.name < b.name;
  });
  return takes;
}

}  // namespace mocap::out
