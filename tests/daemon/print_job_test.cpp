// The job folder (JobFiles) and the job controller (PrintJob) on their own, in virtual time: the
// machine is a fake JobSink whose queue the test works off with the real G-code interpreter, so
// positions, modes and E are the planner's own.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cmath>
#include <deque>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "../planner/planner_test_util.hpp"
#include "daemon/job_files.hpp"
#include "daemon/print_job.hpp"
#include "daemon_fixture.hpp"

namespace feedloop::daemon {
namespace {

using planner::kE;

// The machine: a queue of `capacity` commands, executed when the test says so.
struct FakeMachine final : JobSink {
  planner::test::Rig rig{planner::test::cartesian_config()};
  size_t capacity = 3;
  struct Queued {
    gcode::Command cmd;
    std::string text;
    std::function<void(const Status&)> done;
  };
  std::deque<Queued> queue;
  std::vector<std::string> executed;  // texts, in order
  uint64_t full_answers = 0;
  int heaters_off = 0;
  size_t queued_at_heaters_off = 99;
  size_t executed_at_heaters_off = 0;
  double print_time_s = 0.0;
  double dwelt_ms = 0.0;  // G4 P, summed
  int64_t clock_ns = 0;
  bool refuse = false;
  bool moving = false;   // motion runs (print time anchored on the machine clock)
  double hotend_c = 210.0, min_extrude_temp_c = 0.0;  // as MachineStatus (0: no cold check)
  double ahead_s = 0.0;  // planned motion beyond the motion executing now

  Offer offer(const gcode::Command& cmd, std::string_view text,
              std::function<void(const Status&)> done, std::string* why) override {
    if (refuse) {
      *why = "refused by the test";
      return Offer::kRefused;
    }
    if (queue.size() >= capacity) {
      ++full_answers;
      return Offer::kFull;
    }
    queue.push_back({cmd, std::string(text), std::move(done)});
    return Offer::kAccepted;
  }
  // Executes the oldest queued command; its completion may queue more.
  bool step() {
    if (queue.empty()) return false;
    Queued q = std::move(queue.front());
    queue.pop_front();
    const planner::Vec4 before = rig.interp.state().machine_mm;
    Status st = rig.interp.execute(q.cmd);
    const planner::Vec4 after = rig.interp.state().machine_mm;
    const double d = std::hypot(after[0] - before[0], after[1] - before[1], after[2] - before[2]);
    print_time_s += d / rig.interp.state().feedrate_mm_s;
    if (q.cmd.is('G', 4)) {
      print_time_s += q.cmd.get('P') / 1000.0;
      dwelt_ms += q.cmd.get('P');
    }
    clock_ns += 1'000'000;
    executed.push_back(q.text);
    q.done(st);
    return true;
  }
  void run(int max_steps = 1'000'000) {
    while (max_steps-- > 0 && step()) {
    }
  }
  std::string fault;  // non-empty: the machine faulted with this reason (MachineState::kError)
  engine::MachineStatus machine_status() const override {
    engine::MachineStatus s;
    s.state = queue.empty() ? engine::MachineState::kIdle : engine::MachineState::kBusy;
    if (!fault.empty()) {
      s.state = engine::MachineState::kError;
      std::snprintf(s.last_error, sizeof s.last_error, "%s", fault.c_str());
    }
    for (int i = 0; i < 4; ++i) {
      s.pos_mm[i] = rig.interp.state().logical_mm[static_cast<size_t>(i)];
      s.step_count[i] = std::llround(rig.interp.state().machine_mm[static_cast<size_t>(i)] * 80.0);
      s.encoder_mm[i] = rig.interp.state().machine_mm[static_cast<size_t>(i)];
    }
    s.print_time_s = print_time_s;
    s.planned_until_s = print_time_s + ahead_s;
    s.moving = moving;
    s.hotend_c = hotend_c;
    s.min_extrude_temp_c = min_extrude_temp_c;
    return s;
  }
  int64_t now_ns() const override { return clock_ns; }
  bool input_coming = false;  // as the job last said (set_input_coming)
  int input_reports = 0;
  void set_input_coming(bool coming) override {
    input_coming = coming;
    ++input_reports;
  }
  void all_heaters_off() override {
    ++heaters_off;
    queued_at_heaters_off = queue.size();
    executed_at_heaters_off = executed.size();
  }
  // As engine::Machine::flush: heaters off at once, what is queued now dropped (each completion
  // an error), the motion stopped (here: nothing moves between commands).
  int flushes = 0;
  size_t dropped = 0;
  size_t executed_at_flush = 0, queued_at_flush = 0;
  void cancel_motion() override {
    ++flushes;
    all_heaters_off();  // before anything queued runs or is dropped
    executed_at_flush = executed.size();
    queued_at_flush = queue.size();
    std::deque<Queued> drop;
    drop.swap(queue);
    for (Queued& q : drop) {
      ++dropped;
      q.done(Error{"dropped: the machine's queue was flushed (cancel)"});
    }
  }
};

class PrintJobTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::make_temp_dir("jobs");
    ASSERT_FALSE(dir_.empty());
    files_ = std::make_unique<JobFiles>(dir_ + "/gcodes", 64 * 1024);
    ASSERT_TRUE(files_->open().ok());
    options_.park_x_mm = 5.0;
    options_.park_y_mm = 210.0;
    options_.z_max_mm = 250.0;
    options_.pause_retract_mm = 1.5;
    options_.prime_extra_mm = 0.2;
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  // A small print: home, modes, a square spiral of extruding moves with comments and blanks.
  static std::string part(int moves) {
    std::ostringstream g;
    g << "; a test part\nG28\nG90\nM83\nG1 Z0.3 F600\nG1 X20 Y20 F6000\n\n";
    for (int i = 0; i < moves; ++i) {
      const double x = 20.0 + (i % 4 == 1 || i % 4 == 2 ? 40.0 : 0.0) + 0.1 * i;
      const double y = 20.0 + (i % 4 >= 2 ? 40.0 : 0.0) + 0.1 * i;
      g << "G1 X" << x << " Y" << y << " E0.8 F" << (i % 2 ? 1800 : 2400) << " ; move " << i
        << "\n";
      if (i % 10 == 9) g << "G1 Z" << 0.3 + 0.2 * (i / 10 + 1) << "\n";
    }
    g << "G1 Z20 F600\n";
    return g.str();
  }
  std::vector<std::string> command_lines(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);) {
      auto c = gcode::parse_line(l, SourceLocation{"t", 1, 0});
      if (c && !c->empty()) out.push_back(l);
    }
    return out;
  }

  // The file printed start to end on `m` with no pause (the reference a paused print must match).
  void print_whole(const std::string& file, FakeMachine& m) {
    PrintJob job(*files_, options_, m);
    ASSERT_TRUE(job.start(file).ok());
    m.run();
    job.pump();
    ASSERT_EQ(job.state(), JobState::kComplete);
  }
  std::string dir_;
  std::unique_ptr<JobFiles> files_;
  JobOptions options_;
};

TEST_F(PrintJobTest, FileNamesAreCheckedBeforeAnyFileSystemCall) {
  const std::pair<std::string, std::string> bad[] = {
      {"../escape.gcode", "path separator at byte 3"},
      {"a/b.gcode", "path separator at byte 2"},
      {std::string("nul\0x.gcode", 11), "NUL byte at byte 4"},
      {"bad\xff.gcode", "not valid UTF-8 at byte 4"},
      {"tab\t.gcode", "control character at byte 4"},
      {".hidden.gcode", "starts with '.'"},
      {"..", "starts with '.'"},
      {"notes.txt", "must end in"},
      {"", "empty"},
      {std::string(250, 'a') + ".gcode", "256 bytes long"},
  };
  for (const auto& [name, why] : bad) {
    Status s = JobFiles::validate_name(name);
    ASSERT_FALSE(s.ok()) << name;
    EXPECT_NE(s.error().message.find(why), std::string::npos) << s.error().message;
    EXPECT_FALSE(files_->write(name, "G28\n").ok());
  }
  EXPECT_TRUE(JobFiles::validate_name("Benchy ü 0.2mm.gcode").ok());
  EXPECT_TRUE(JobFiles::validate_name("CUBE.GCO").ok());
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/escape.gcode"));
}

TEST_F(PrintJobTest, UploadListDeleteAndSizeLimit) {
  ASSERT_TRUE(files_->write("b.gcode", "G28\nG1 X1\n").ok());
  auto a = files_->write("a.gcode", std::string(1000, ';'));
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->size_bytes, 1000u);
  // Above the limit: refused, and nothing (not even the temporary) is left.
  auto big = files_->write("big.gcode", std::string(64 * 1024 + 1, 'G'));
  ASSERT_FALSE(big.ok());
  EXPECT_NE(big.error().message.find("65537 bytes"), std::string::npos) << big.error().message;
  std::ofstream(dir_ + "/gcodes/stray.bin") << "x";  // not a G-code name: not listed
  auto list = files_->list();
  ASSERT_TRUE(list.ok());
  ASSERT_EQ(list->size(), 2u);
  EXPECT_EQ((*list)[0].name, "a.gcode");
  EXPECT_EQ((*list)[1].name, "b.gcode");
  EXPECT_EQ((*list)[1].size_bytes, 10u);
  size_t entries = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir_ + "/gcodes"))
    entries += e.path().filename() != "" ? 1 : 0;
  EXPECT_EQ(entries, 3u);  // a, b, stray: no temporary left behind
  struct stat st {};
  ASSERT_EQ(::stat((dir_ + "/gcodes/a.gcode").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
  ASSERT_TRUE(files_->remove("a.gcode").ok());
  Status again = files_->remove("a.gcode");
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message.find("no job file named 'a.gcode'"), std::string::npos);
}

TEST_F(PrintJobTest, RunsAFileFromStartToEndPacedByTheQueue) {
  const std::string text = part(60);
  ASSERT_TRUE(files_->write("part.gcode", text).ok());
  FakeMachine m;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("part.gcode").ok());
  EXPECT_EQ(job.state(), JobState::kPrinting);
  EXPECT_EQ(m.queue.size(), 3u);  // no more than the queue takes
  while (m.step()) job.pump();
  job.pump();
  EXPECT_EQ(job.state(), JobState::kComplete);
  EXPECT_EQ(m.executed, command_lines(text));  // every command, in order, nothing else
  EXPECT_GT(m.full_answers, 0u);
  const JobStatus s = job.status();
  EXPECT_EQ(s.bytes_submitted, text.size());
  EXPECT_DOUBLE_EQ(s.progress_bytes, 1.0);
  EXPECT_NEAR(s.print_time_s, m.print_time_s, 1e-9);
  EXPECT_EQ(m.heaters_off, 0);
}

// The job tells the machine while lines of its file are still to come (in virtual time the machine
// then keeps its lookahead for them instead of stopping the motion): from the start while printing,
// not while paused, again on resume, and no longer once the file is read to its end or the job
// ends.
TEST_F(PrintJobTest, SaysWhileLinesOfTheFileAreStillToCome) {
  const std::string text = part(60);
  ASSERT_TRUE(files_->write("part.gcode", text).ok());
  FakeMachine m;
  PrintJob job(*files_, options_, m);
  EXPECT_FALSE(m.input_coming);
  ASSERT_TRUE(job.start("part.gcode").ok());
  EXPECT_TRUE(m.input_coming);
  for (int i = 0; i < 20; ++i) m.step();
  job.pump();
  EXPECT_TRUE(m.input_coming);
  ASSERT_TRUE(job.pause().ok());
  EXPECT_FALSE(m.input_coming);  // the pause's own moves: the machine may release them at once
  m.run();
  ASSERT_EQ(job.state(), JobState::kPaused);
  EXPECT_FALSE(m.input_coming);
  ASSERT_TRUE(job.resume().ok());
  EXPECT_FALSE(m.input_coming);  // the return moves first
  while (job.state() == JobState::kResuming && m.step()) {
  }
  ASSERT_EQ(job.state(), JobState::kPrinting);
  EXPECT_TRUE(m.input_coming);
  // Read to the end: the last lines are queued, nothing more comes (the lookahead may be released).
  bool said_done_before_complete = false;
  while (m.step()) {
    job.pump();
    if (!m.input_coming && job.state() == JobState::kPrinting) said_done_before_complete = true;
  }
  job.pump();
  EXPECT_EQ(job.state(), JobState::kComplete);
  EXPECT_TRUE(said_done_before_complete);
  EXPECT_FALSE(m.input_coming);
  EXPECT_LE(m.input_reports, 6);  // said on a change only, not at every pump
  // A job that ends in error says so too.
  FakeMachine f;
  PrintJob failing(*files_, options_, f);
  ASSERT_TRUE(failing.start("part.gcode").ok());
  EXPECT_TRUE(f.input_coming);
  f.fault = "following error beyond the limit";
  failing.pump();
  EXPECT_EQ(failing.state(), JobState::kError);
  EXPECT_FALSE(f.input_coming);
}

// A machine that faults mid-print (an encoder fault, a following error) runs nothing more: the
// job ends in error with its reason and the heaters off, instead of "printing" forever.
TEST_F(PrintJobTest, AMachineFaultEndsTheJobInError) {
  ASSERT_TRUE(files_->write("part.gcode", part(60)).ok());
  FakeMachine m;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("part.gcode").ok());
  for (int i = 0; i < 10; ++i) {
    m.step();
    job.pump();
  }
  EXPECT_EQ(job.state(), JobState::kPrinting);
  const size_t executed = m.executed.size();
  m.fault = "MCU 'mcu_x' reports device loop: implausible encoder readings";
  job.pump();
  EXPECT_EQ(job.state(), JobState::kError);
  EXPECT_EQ(job.status().message,
            "the machine stopped: MCU 'mcu_x' reports device loop: implausible encoder readings");
  EXPECT_EQ(m.heaters_off, 1);
  job.pump();
  EXPECT_EQ(m.executed.size(), executed);  // nothing more offered
  // A job started on a faulted machine ends at once, saying why.
  ASSERT_TRUE(job.start("part.gcode").ok());
  job.pump();
  EXPECT_EQ(job.state(), JobState::kError);
}

TEST_F(PrintJobTest, ProgressAndEstimateComeFromThePlannedTime) {
  const std::string text = part(200);
  ASSERT_TRUE(files_->write("part.gcode", text).ok());
  FakeMachine m;
  m.capacity = 8;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("part.gcode").ok());
  for (int i = 0; i < 120; ++i) m.step();
  const JobStatus mid = job.status();
  ASSERT_EQ(mid.state, JobState::kPrinting);
  EXPECT_GT(mid.progress_bytes, 0.3);
  EXPECT_LT(mid.progress_bytes, 0.95);
  m.run();
  job.pump();
  const double total = m.print_time_s;
  // The estimate at that point (planned time per byte, scaled to the file) against the real total.
  EXPECT_NEAR(mid.estimated_total_s, total, 0.15 * total)
      << "mid " << mid.estimated_total_s << " total " << total;
  EXPECT_NEAR(mid.estimated_remaining_s, mid.estimated_total_s - mid.print_time_s, 1e-9);
  EXPECT_GT(mid.progress_time, 0.2);
  const JobStatus end = job.status();
  EXPECT_EQ(end.state, JobState::kComplete);
  EXPECT_NEAR(end.estimated_total_s, total, 1e-9);
  EXPECT_DOUBLE_EQ(end.estimated_remaining_s, 0.0);
}

// Pause in the middle, resume: the machine returns to the recorded X Y Z E with the file's modes
// and feedrate, and the print ends exactly where the same file ends without a pause.
TEST_F(PrintJobTest, PauseParksAndResumeRestoresPositionModesAndFeedrate) {
  const std::string text = part(80);
  ASSERT_TRUE(files_->write("part.gcode", text).ok());
  FakeMachine plain;
  ASSERT_NO_FATAL_FAILURE(print_whole("part.gcode", plain));
  FakeMachine m;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("part.gcode").ok());
  for (int i = 0; i < 40; ++i) m.step();
  ASSERT_TRUE(job.pause().ok());
  EXPECT_EQ(job.state(), JobState::kPausing);
  const size_t file_lines_before = m.executed.size() + m.queue.size();
  m.run();
  EXPECT_EQ(job.state(), JobState::kPaused);
  const JobStatus p = job.status();
  ASSERT_TRUE(p.pause_position.valid);
  // The pause position is where the last queued file command left the machine.
  const std::vector<std::string> lines = command_lines(text);
  EXPECT_EQ(std::vector<std::string>(m.executed.begin(),
                                     m.executed.begin() + static_cast<long>(file_lines_before)),
            std::vector<std::string>(lines.begin(),
                                     lines.begin() + static_cast<long>(file_lines_before)));
  // Parked: retracted by 1.5 mm, Z up 5 mm, at the park point.
  const auto& st = m.rig.interp.state();
  EXPECT_DOUBLE_EQ(st.logical_mm[0], 5.0);
  EXPECT_DOUBLE_EQ(st.logical_mm[1], 210.0);
  EXPECT_NEAR(st.logical_mm[2], p.pause_position.pos_mm[2] + 5.0, 1e-9);
  EXPECT_NEAR(st.logical_mm[kE], p.pause_position.pos_mm[3] - 1.5, 1e-9);
  // Another client moves the machine and changes modes while paused: resume puts them back.
  for (const char* l : {"G91", "M82", "G1 X10 F300"}) {
    m.queue.push_back(
        {*gcode::parse_line(l, SourceLocation{"other", 1, 0}), l, [](const Status&) {}});
  }
  m.run();
  ASSERT_TRUE(job.resume().ok());
  // Run up to the end of the return sequence: the job measures the return position there.
  while (job.state() == JobState::kResuming && m.step()) {
  }
  const JobStatus r = job.status();
  ASSERT_TRUE(r.resume_position.valid);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(r.resume_position.pos_mm[i], p.pause_position.pos_mm[i], 1e-9) << "axis " << i;
    EXPECT_EQ(r.resume_position.step_count[i] - p.pause_position.step_count[i],
              i == 3 ? std::llround(0.2 * 80) : 0)
        << "axis " << i;  // E: the prime beyond the retract is extruded; X Y Z: the same step
  }
  m.run();
  job.pump();
  EXPECT_EQ(job.state(), JobState::kComplete);
  EXPECT_FALSE(m.rig.interp.state().relative_xyz);
  EXPECT_TRUE(m.rig.interp.state().e_relative());
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(st.logical_mm[i], plain.rig.interp.state().logical_mm[i], 1e-9);
  EXPECT_NEAR(st.logical_mm[kE], plain.rig.interp.state().logical_mm[kE], 1e-9);
  // The feedrate the file left (F2400 or F1800 of the last move before the pause) was restored:
  // the file's next moves without F ran at it. The Z moves have no F: compare the last feedrate.
  EXPECT_DOUBLE_EQ(st.feedrate_mm_s, plain.rig.interp.state().feedrate_mm_s);
  EXPECT_EQ(job.status().pauses, 1u);
  EXPECT_EQ(m.heaters_off, 0);  // heaters held on pause
}

// The slicers' pauses in the file: M600 (filament change), M0 / M1 (Cura's pause at height, with
// the text Marlin shows on its panel) pause the job there as M25 does, and the message says which
// and where; M0 with S (Marlin: wait that long for a click) dwells and goes on.
TEST_F(PrintJobTest, TheFilesM600M0AndM1PauseTheJobWithTheirMessage) {
  const std::string base = part(40);
  std::vector<std::string> lines;
  {
    std::istringstream in(base);
    for (std::string l; std::getline(in, l);) lines.push_back(l);
  }
  // Inserted after the file's moves 8, 16, 24 and 32 (their lines end in "; move N").
  const std::vector<std::pair<std::string, std::string>> inserts = {
      {"; move 8", "M600 ; colour change"},
      {"; move 16", "M0 Insert the magnets ; pause at height"},
      {"; move 24", "M0 S0.5 ; dwell"},
      {"; move 32", "M1"}};
  std::string text;
  std::vector<int> line_of;  // 1-based line of each insert
  int n = 0;
  for (const std::string& l : lines) {
    text += l + "\n";
    ++n;
    for (const auto& [after, what] : inserts) {
      if (l.size() >= after.size() &&
          l.compare(l.size() - after.size(), after.size(), after) == 0) {
        text += what + "\n";
        line_of.push_back(++n);
      }
    }
  }
  ASSERT_EQ(line_of.size(), 4u);
  ASSERT_TRUE(files_->write("part.gcode", text).ok());
  options_.settle_ms = 0;
  FakeMachine plain;
  ASSERT_TRUE(files_->write("plain.gcode", base).ok());
  ASSERT_NO_FATAL_FAILURE(print_whole("plain.gcode", plain));
  FakeMachine m;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("part.gcode").ok());
  const std::vector<std::string> expected = {
      "filament change (M600): load the new filament (part.gcode:" + std::to_string(line_of[0]) +
          "); resume to go on",
      "paused by M0: Insert the magnets (part.gcode:" + std::to_string(line_of[1]) +
          "); resume to go on",
      "paused by M1 (part.gcode:" + std::to_string(line_of[3]) + "); resume to go on"};
  for (const std::string& message : expected) {
    m.run();
    job.pump();
    ASSERT_EQ(job.state(), JobState::kPaused) << message;
    EXPECT_EQ(job.status().message, message);
    // Parked (the park point), as M25 parks.
    EXPECT_DOUBLE_EQ(m.rig.interp.state().logical_mm[0], 5.0);
    EXPECT_DOUBLE_EQ(m.rig.interp.state().logical_mm[1], 210.0);
    ASSERT_TRUE(job.resume().ok());
    EXPECT_EQ(job.status().message, "");
  }
  m.run();
  job.pump();
  EXPECT_EQ(job.state(), JobState::kComplete);
  EXPECT_EQ(job.status().pauses, 3u);
  EXPECT_EQ(m.heaters_off, 0);
  // M0 S0.5 ran as a dwell of 500 ms (the pauses' settle dwells are 0 here).
  EXPECT_EQ(std::count(m.executed.begin(), m.executed.end(), "M0 S0.5 ; dwell"), 1);
  EXPECT_DOUBLE_EQ(m.dwelt_ms, 500.0);
  for (const char* pause : {"M600 ; colour change", "M1"})
    EXPECT_EQ(std::count(m.executed.begin(), m.executed.end(), pause), 0) << pause;
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(m.rig.interp.state().logical_mm[i], plain.rig.interp.state().logical_mm[i], 1e-9);
  EXPECT_NEAR(m.rig.interp.state().logical_mm[kE], plain.rig.interp.state().logical_mm[kE], 1e-9);
}

// A cold hotend (below min_extrude_temp) would refuse the park's retract and the resume's prime:
// the pause then retracts nothing (as Marlin's), the file's message stays, and the resume primes
// nothing. A pause that did retract is not resumed cold: the resume is refused with the reason and
// the job stays paused, until the hotend is hot again.
TEST_F(PrintJobTest, AColdHotendIsNotRetractedAndAColdResumeIsRefused) {
  const std::string base = part(24);
  std::string text;
  {
    std::istringstream in(base);
    for (std::string l; std::getline(in, l);) {
      text += l + "\n";
      if (l.find("; move 8") != std::string::npos || l.find("; move 16") != std::string::npos)
        text += "M600\n";
    }
  }
  ASSERT_TRUE(files_->write("part.gcode", text).ok());
  ASSERT_TRUE(files_->write("plain.gcode", base).ok());
  options_.settle_ms = 0;
  FakeMachine plain;
  ASSERT_NO_FATAL_FAILURE(print_whole("plain.gcode", plain));
  FakeMachine m;
  m.min_extrude_temp_c = 170.0;
  m.hotend_c = 25.0;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("part.gcode").ok());
  auto e_lines = [&m] {
    return std::count_if(m.executed.begin(), m.executed.end(),
                         [](const std::string& l) { return l.rfind("G1 E", 0) == 0; });
  };
  // 1. Cold at the pause: parked without a retract, the M600 message kept.
  m.run();
  job.pump();
  ASSERT_EQ(job.state(), JobState::kPaused);
  EXPECT_EQ(e_lines(), 0);
  EXPECT_EQ(job.status().message.rfind("filament change (M600)", 0), 0u) << job.status().message;
  const double e_paused = m.rig.interp.state().logical_mm[kE];
  EXPECT_NEAR(e_paused, job.status().pause_position.pos_mm[3], 1e-9);
  ASSERT_TRUE(job.resume().ok());  // nothing to prime: a cold resume is allowed
  // 2. Hot at the second pause: retracted; cooled while paused, the resume is refused.
  m.hotend_c = 215.0;
  m.run();
  job.pump();
  ASSERT_EQ(job.state(), JobState::kPaused);
  EXPECT_EQ(e_lines(), 1);  // the retract
  EXPECT_NEAR(m.rig.interp.state().logical_mm[kE], job.status().pause_position.pos_mm[3] - 1.5,
              1e-9);
  m.hotend_c = 120.0;
  const Status cold = job.resume();
  ASSERT_FALSE(cold.ok());
  EXPECT_NE(cold.error().to_string().find("hotend is at 120.0 C, below min_extrude_temp 170 C"),
            std::string::npos)
      << cold.error().to_string();
  EXPECT_EQ(job.state(), JobState::kPaused);
  const size_t executed = m.executed.size();
  m.run();
  EXPECT_EQ(m.executed.size(), executed);  // nothing moved
  m.hotend_c = 212.0;
  ASSERT_TRUE(job.resume().ok());
  m.run();
  job.pump();
  EXPECT_EQ(job.state(), JobState::kComplete);
  EXPECT_EQ(e_lines(), 2);  // the retract and the prime: nothing for the cold first pause
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(m.rig.interp.state().logical_mm[i], plain.rig.interp.state().logical_mm[i], 1e-9);
  EXPECT_NEAR(m.rig.interp.state().logical_mm[kE], plain.rig.interp.state().logical_mm[kE], 1e-9);
}

TEST_F(PrintJobTest, CancelFlushesTheQueueTurnsHeatersOffAtOnceThenParks) {
  ASSERT_TRUE(files_->write("part.gcode", part(80)).ok());
  FakeMachine m;
  m.capacity = 5;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("part.gcode").ok());
  for (int i = 0; i < 30; ++i) m.step();
  const size_t executed = m.executed.size();
  const size_t queued = m.queue.size();
  ASSERT_EQ(queued, 5u);
  ASSERT_TRUE(job.cancel().ok());
  // At once: the heaters off and the queued commands dropped (not run), no error for them.
  EXPECT_EQ(m.flushes, 1);
  EXPECT_EQ(m.dropped, queued);
  EXPECT_GE(m.heaters_off, 1);
  EXPECT_EQ(m.executed_at_flush, executed);
  EXPECT_EQ(m.queued_at_flush, queued);
  EXPECT_EQ(job.state(), JobState::kCancelling);
  EXPECT_EQ(job.status().message, "");
  m.run();
  EXPECT_EQ(job.state(), JobState::kCancelled);
  EXPECT_EQ(m.executed[executed], "G21");  // the park sequence follows the last executed line
  EXPECT_EQ(job.status().message, "");
  EXPECT_DOUBLE_EQ(m.rig.interp.state().logical_mm[0], 5.0);
  EXPECT_DOUBLE_EQ(m.rig.interp.state().logical_mm[1], 210.0);
  EXPECT_FALSE(job.active());
  EXPECT_FALSE(job.cancel().ok());
  // Cancel while paused: the heaters go off, no second park.
  ASSERT_TRUE(job.start().ok());
  for (int i = 0; i < 20; ++i) m.step();
  ASSERT_TRUE(job.pause().ok());
  m.run();
  ASSERT_EQ(job.state(), JobState::kPaused);
  const size_t before = m.executed.size();
  const int heaters_off = m.heaters_off;
  ASSERT_TRUE(job.cancel().ok());
  m.run();
  EXPECT_EQ(job.state(), JobState::kCancelled);
  EXPECT_EQ(m.flushes, 1);  // paused: nothing of the job queued, no flush
  EXPECT_EQ(m.heaters_off, heaters_off + 2);  // at the cancel, and behind the (empty) queue
  EXPECT_EQ(m.executed.size(), before);
}

TEST_F(PrintJobTest, ABadLineEndsTheJobWithItsLocationAndHeatersOff) {
  ASSERT_TRUE(files_->write("bad.gcode", "G28\nG1 X10 F3000\nG1 X20 Q\nG1 X30\n").ok());
  FakeMachine m;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("bad.gcode").ok());
  m.run();
  EXPECT_EQ(job.state(), JobState::kError);
  EXPECT_NE(job.status().message.find("bad.gcode:3"), std::string::npos) << job.status().message;
  EXPECT_EQ(m.heaters_off, 1);
  EXPECT_EQ(m.executed.size(), 2u);  // the lines before it ran, nothing after
  // A move the machine refuses (outside the travel) also ends it, naming the line.
  ASSERT_TRUE(files_->write("far.gcode", "G28\nG1 X10 F3000\nG1 X999\nG1 X30\n").ok());
  ASSERT_TRUE(job.start("far.gcode").ok());
  m.run();
  EXPECT_EQ(job.state(), JobState::kError);
  const std::string far = job.status().message;
  EXPECT_EQ(far.rfind("far.gcode:3: ", 0), 0u) << far;
  EXPECT_EQ(far.find("far.gcode:", 1), std::string::npos) << far;  // named once
}

// A file that cannot be read to its end (here: replaced by a directory after it was selected, so
// that every read fails with EISDIR) ends the job in error, naming the file: it completed, having
// run none of it.
TEST_F(PrintJobTest, AReadErrorEndsTheJobInErrorNotComplete) {
  ASSERT_TRUE(files_->write("gone.gcode", part(10)).ok());
  FakeMachine m;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.select("gone.gcode").ok());
  std::filesystem::remove(dir_ + "/gcodes/gone.gcode");
  std::filesystem::create_directory(dir_ + "/gcodes/gone.gcode");
  ASSERT_TRUE(job.start("").ok());
  m.run();
  job.pump();
  EXPECT_EQ(job.state(), JobState::kError);
  EXPECT_NE(job.status().message.find("gone.gcode: read error after line 0"), std::string::npos)
      << job.status().message;
  EXPECT_NE(job.status().message.find("Is a directory"), std::string::npos) << job.status().message;
  EXPECT_TRUE(m.executed.empty());
  EXPECT_EQ(m.heaters_off, 1);
}

TEST_F(PrintJobTest, SelectStartByteAndRefusals) {
  const std::string text = "G28\nG1 X10 F3000\nG1 X20\nG1 X30\n";
  ASSERT_TRUE(files_->write("s.gcode", text).ok());
  FakeMachine m;
  PrintJob job(*files_, options_, m);
  EXPECT_FALSE(job.start().ok());  // nothing selected
  EXPECT_FALSE(job.pause().ok());
  EXPECT_FALSE(job.resume().ok());
  auto missing = job.select("nope.gcode");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("no job file named 'nope.gcode'"), std::string::npos);
  // PrusaSlicer's binary G-code uploaded by mistake: refused at the selection, with what it is.
  ASSERT_TRUE(files_->write("b.gcode", std::string("GCDE\x01\0\0\0G1 X1\n", 14)).ok());
  auto binary = job.select("b.gcode");
  ASSERT_FALSE(binary.ok());
  EXPECT_NE(binary.error().message.find("'b.gcode' is not G-code: binary G-code"),
            std::string::npos)
      << binary.error().message;
  EXPECT_FALSE(job.start("b.gcode").ok());
  EXPECT_EQ(job.state(), JobState::kIdle);
  ASSERT_TRUE(job.select("s.gcode").ok());
  EXPECT_FALSE(job.set_start_byte(text.size() + 1).ok());
  // M26 S6 falls inside "G1 X10 F3000": that line is skipped whole, the next one is first.
  ASSERT_TRUE(job.set_start_byte(6).ok());
  ASSERT_TRUE(job.start().ok());
  EXPECT_FALSE(job.start("s.gcode").ok());  // one job at a time
  EXPECT_FALSE(job.select("s.gcode").ok());
  m.run();
  EXPECT_EQ(job.state(), JobState::kComplete);
  EXPECT_EQ(m.executed, (std::vector<std::string>{"G1 X20", "G1 X30"}));
}

// print_stats.filament_used (Klipper: the E the print moved, net): counted from the file's lines
// in their modes, it equals what the interpreter's machine E (which G92 does not move) went
// through: absolute E with G92 E0 resets and retracts, M83, G91/G90 (which set E's mode too) and
// G20. With a pause in the middle, the job's own retract and prime are not counted (only the
// prime beyond the retract, prime_extra_mm, moves the machine's E without being filament used).
TEST_F(PrintJobTest, FilamentUsedFollowsTheFilesEModes) {
  const std::string text =
      "G28\nG90\nM82\nG92 E0\nG1 X10 Y10 E2.5 F3000\nG1 X20 E4.0\nG1 E3.2 F1800\n"  // retract
      "G92 E0\nG1 X30 E1.25\nG1 X40 E3.0\nM83\nG1 X50 E0.75\nG1 E-0.4\nG1 X60 E0.4\n"
      "G91\nG1 X5 E0.6\nG1 Y5 E0.5\nG90\nG92 E10\nG1 X70 E10.5\nG92 E0\nG20\nG1 X3 E0.02\n"
      "G21\nG1 X80 Y20 E1\n";
  ASSERT_TRUE(files_->write("e.gcode", text).ok());
  // By hand, segment by segment (G20: E0.02 in = 0.508 mm).
  const double by_hand = (2.5 + 1.5 - 0.8) + (1.25 + 1.75) + (0.75 - 0.4 + 0.4) + (0.6 + 0.5) +
                         0.5 + 0.508 + (1.0 - 0.508);
  FakeMachine m;
  m.capacity = 4;
  const double e0 = m.rig.interp.state().machine_mm[kE];
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("e.gcode").ok());
  m.run();
  job.pump();
  ASSERT_EQ(job.state(), JobState::kComplete);
  const double machine_e = m.rig.interp.state().machine_mm[kE] - e0;
  EXPECT_NEAR(job.status().filament_used_mm, machine_e, 1e-9);
  EXPECT_NEAR(job.status().filament_used_mm, by_hand, 1e-9);

  // Again with a pause after a few lines: the same filament, the machine's E moved by the prime
  // beyond the retract as well.
  FakeMachine p;
  p.capacity = 2;
  const double p0 = p.rig.interp.state().machine_mm[kE];
  PrintJob paused(*files_, options_, p);
  ASSERT_TRUE(paused.start("e.gcode").ok());
  for (int i = 0; i < 8; ++i) p.step();
  ASSERT_TRUE(paused.pause().ok());
  p.run();
  ASSERT_EQ(paused.state(), JobState::kPaused);
  const double at_pause = paused.status().filament_used_mm;
  EXPECT_GT(at_pause, 0.0);
  EXPECT_LT(at_pause, by_hand);
  ASSERT_TRUE(paused.resume().ok());
  p.run();
  paused.pump();
  ASSERT_EQ(paused.state(), JobState::kComplete);
  EXPECT_NEAR(paused.status().filament_used_mm, by_hand, 1e-9);
  EXPECT_NEAR(p.rig.interp.state().machine_mm[kE] - p0, by_hand + options_.prime_extra_mm, 1e-9);
}

// Klipper's virtual_sdcard reads ahead of the motion by about 2 s; so does the job: no line is
// handed over while the moving machine holds more planned motion than read_ahead_s, and a pause
// then stops the print within about that much.
TEST_F(PrintJobTest, ReadsAheadOfTheMotionByAtMostReadAheadS) {
  ASSERT_TRUE(files_->write("part.gcode", part(20)).ok());
  FakeMachine m;
  m.capacity = 50;
  m.moving = true;
  m.ahead_s = 2.5;  // above the default 2 s
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("part.gcode").ok());
  EXPECT_EQ(m.queue.size(), 0u);
  EXPECT_EQ(job.status().bytes_submitted, 0u);
  m.ahead_s = 1.9;
  job.pump();
  EXPECT_EQ(m.queue.size(), 28u);  // every command of the part: the fake's plan does not grow
  m.run();
  job.pump();
  EXPECT_EQ(job.state(), JobState::kComplete);
  EXPECT_EQ(m.executed.size(), 28u);
}

// A UI shows "paused" as soon as it asked; a resume that comes while the head still parks is
// kept and runs once parked (the pause position taken first), and the file ends as without it.
TEST_F(PrintJobTest, AResumeWhilePausingRunsOnceParked) {
  const std::string text = part(40);
  ASSERT_TRUE(files_->write("part.gcode", text).ok());
  FakeMachine m;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("part.gcode").ok());
  for (int i = 0; i < 20; ++i) m.step();
  ASSERT_TRUE(job.pause().ok());
  ASSERT_TRUE(job.resume().ok());
  EXPECT_EQ(job.state(), JobState::kPausing);
  m.run();
  job.pump();
  EXPECT_EQ(job.state(), JobState::kComplete);
  const JobStatus s = job.status();
  EXPECT_TRUE(s.pause_position.valid);
  EXPECT_TRUE(s.resume_position.valid);
  EXPECT_EQ(s.pauses, 1u);
  for (int i = 0; i < 3; ++i)  // back where it paused
    EXPECT_NEAR(s.resume_position.pos_mm[i], s.pause_position.pos_mm[i], 1e-9);
  const std::vector<std::string> lines = command_lines(text);
  EXPECT_EQ(m.executed.back(), lines.back());
  // A cancel while pausing wins over an earlier resume.
  ASSERT_TRUE(job.start("part.gcode").ok());
  for (int i = 0; i < 20; ++i) m.step();
  ASSERT_TRUE(job.pause().ok());
  ASSERT_TRUE(job.resume().ok());
  ASSERT_TRUE(job.cancel().ok());
  m.run();
  job.pump();
  EXPECT_EQ(job.state(), JobState::kCancelled);
}

TEST_F(PrintJobTest, ARefusedOfferEndsTheJob) {
  ASSERT_TRUE(files_->write("s.gcode", "G28\nG1 X10 F3000\n").ok());
  FakeMachine m;
  m.refuse = true;
  PrintJob job(*files_, options_, m);
  ASSERT_TRUE(job.start("s.gcode").ok());
  EXPECT_EQ(job.state(), JobState::kError);
  EXPECT_NE(job.status().message.find("s.gcode:1: refused by the test"), std::string::npos)
      << job.status().message;
}

}  // namespace
}  // namespace feedloop::daemon
