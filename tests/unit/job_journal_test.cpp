// The --state_dir journal: jobs saved and loaded back with their finished frames, the
// tolerance that lets a daemon killed mid-write restart (a torn last frames.log line, corrupt
// or foreign entries skipped with a warning), ids refused before they can become paths, scene
// archives (nested names, the byte limit, leftovers of a crash removed by Open), and the
// atomic file helpers.
#include "server/job_journal.h"

#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "tests/unit/status_matchers.h"

namespace tessera::server {
namespace {

namespace fs = std::filesystem;
using test::IsError;

constexpr char kJobA[] = "0123456789abcdef";
constexpr char kJobB[] = "fedcba9876543210";

std::string Sha(char c) { return std::string(64, c); }  // a well-formed sha256 text

std::string SceneIdOf(char c) { return std::string(64, c); }

void WriteRaw(const std::string& path, const std::string& bytes, bool append = false) {
  std::ofstream out(path, std::ios::binary | (append ? std::ios::app : std::ios::trunc));
  ASSERT_TRUE(out) << "cannot open " << path;
  out << bytes;
  ASSERT_TRUE(out.flush()) << "cannot write " << path;
}

// Names in `dir`, sorted ("" entries never occur).
std::vector<std::string> Names(const std::string& dir) {
  std::vector<std::string> names;
  for (const fs::directory_entry& e : fs::directory_iterator(dir))
    names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

bool AnyContains(const std::vector<std::string>& lines, const std::string& needle) {
  return std::any_of(lines.begin(), lines.end(), [&](const std::string& line) {
    return line.find(needle) != std::string::npos;
  });
}

std::string Join(const std::vector<std::string>& lines) {
  std::string out;
  for (const std::string& line : lines) out += line + "\n";
  return out;
}

v1::Job MakeJob(const std::string& id, double created) {
  v1::Job job;
  job.set_job_id(id);
  job.set_state(v1::JOB_RUNNING);
  job.set_frames_total(24);
  job.set_frames_done(3);
  job.set_created_unix_s(created);
  job.set_scene_id(SceneIdOf('c'));
  v1::JobSpec* spec = job.mutable_spec();
  spec->set_name("shot 1 — flythrough");  // non-ASCII UTF-8 survives
  spec->set_scene_id("cccc");
  spec->mutable_frames()->set_first(1);
  spec->mutable_frames()->set_last(24);
  spec->set_output(v1::JOB_OUTPUT_RETURN);
  spec->set_name_pattern("shot1_%04d.png");
  v1::CameraKeyframe* key = spec->mutable_path()->add_keyframes();
  key->set_frame(1);
  key->mutable_look_at()->mutable_eye()->set_z(5.0f);
  key->set_yfov(0.7f);
  return job;
}

JobFrameRecord Frame(uint32_t frame, uint64_t bytes, char sha) {
  return JobFrameRecord{frame, bytes, Sha(sha)};
}

std::vector<uint32_t> FrameNumbers(const std::vector<JobFrameRecord>& frames) {
  std::vector<uint32_t> numbers;
  for (const JobFrameRecord& f : frames) numbers.push_back(f.frame);
  return numbers;
}

std::vector<uint8_t> Bytes(const std::string& s) {
  return std::vector<uint8_t>(s.begin(), s.end());
}

// A glTF file set with a nested name, binary data (zeros included) and an empty file.
GltfSource MakeScene() {
  GltfSource source;
  source.main_file = "scene.gltf";
  source.files["scene.gltf"] = Bytes(R"({"asset":{"version":"2.0"}})");
  std::vector<uint8_t> buffer(1000);
  for (size_t i = 0; i < buffer.size(); ++i) buffer[i] = static_cast<uint8_t>(i * 7);
  source.files["buffers/data.bin"] = buffer;
  source.files["textures/a.png"] = Bytes(std::string("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16));
  source.files["empty.bin"] = {};
  return source;
}

uint64_t TotalBytes(const GltfSource& source) {
  uint64_t total = 0;
  for (const auto& [name, data] : source.files) total += data.size();
  return total;
}

class JobJournalTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = ::testing::TempDir() + "/tessera_job_journal_XXXXXX";
    ASSERT_NE(mkdtemp(tmpl.data()), nullptr) << tmpl << ": " << std::strerror(errno);
    root_ = tmpl;
    state_ = root_ + "/state";
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }

  // A journal on state_, as a (re)started daemon opens it.
  std::unique_ptr<JobJournal> OpenJournal() {
    absl::StatusOr<std::unique_ptr<JobJournal>> journal = JobJournal::Open(state_);
    EXPECT_TRUE(journal.ok()) << journal.status();
    return journal.ok() ? *std::move(journal) : nullptr;
  }

  std::string JobPath(const std::string& id, const std::string& file) const {
    return state_ + "/jobs/" + id + "/" + file;
  }

  std::string root_;   // removed after the test
  std::string state_;  // root_/state: Open creates it
};

// ---------------------------------------------------------------------------------------------
// Jobs

TEST_F(JobJournalTest, SavedJobLoadsBackAfterARestart) {
  v1::Job job = MakeJob(kJobA, 1000.5);
  {
    std::unique_ptr<JobJournal> journal = OpenJournal();
    ASSERT_NE(journal, nullptr);
    EXPECT_EQ(journal->dir(), state_);
    ASSERT_TRUE(journal->SaveJob(job).ok());
    // Replaced, not appended to: the last save is what loads.
    job.set_state(v1::JOB_SUCCEEDED);
    job.set_frames_done(24);
    job.set_finished_unix_s(2000.25);
    ASSERT_TRUE(journal->SaveJob(job).ok());
    EXPECT_EQ(journal->FramesDir(kJobA), JobPath(kJobA, "frames"));
    EXPECT_TRUE(fs::is_directory(journal->FramesDir(kJobA)));
  }
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  EXPECT_TRUE(warnings.empty()) << Join(warnings);
  ASSERT_EQ(jobs.size(), 1u);
  const v1::Job& loaded = jobs[0].job;
  EXPECT_EQ(loaded.job_id(), kJobA);
  EXPECT_EQ(loaded.state(), v1::JOB_SUCCEEDED);
  EXPECT_EQ(loaded.frames_done(), 24u);
  EXPECT_EQ(loaded.spec().name(), "shot 1 — flythrough");
  EXPECT_EQ(loaded.spec().path().keyframes(0).look_at().eye().z(), 5.0f);
  EXPECT_EQ(loaded.SerializeAsString(), job.SerializeAsString());
  EXPECT_TRUE(jobs[0].frames.empty());
  // Only job.pb, frames/ (no frames.log before the first frame, no temporary file).
  EXPECT_EQ(Names(state_ + "/jobs/" + kJobA), (std::vector<std::string>{"frames", "job.pb"}));
}

TEST_F(JobJournalTest, JobsLoadOldestFirst) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 200)).ok());  // sorts first by id, is newer
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobB, 100)).ok());
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  ASSERT_EQ(jobs.size(), 2u) << Join(warnings);
  EXPECT_EQ(jobs[0].job.job_id(), kJobB);
  EXPECT_EQ(jobs[1].job.job_id(), kJobA);
}

TEST_F(JobJournalTest, AppendedFramesLoadInLogOrderAndTheLastDuplicateWins) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  ASSERT_TRUE(journal->AppendFrame(kJobA, Frame(5, 100, 'a')).ok());
  ASSERT_TRUE(journal->AppendFrame(kJobA, Frame(1, 200, 'b')).ok());
  ASSERT_TRUE(journal->AppendFrame(kJobA, Frame(3, 300, 'c')).ok());
  ASSERT_TRUE(journal->AppendFrame(kJobA, Frame(1, 4000000000000, 'd')).ok());  // re-rendered

  const std::string first_line = "5 100 " + Sha('a') + "\n";
  const std::string log = *ReadWholeFile(JobPath(kJobA, "frames.log"), 1 << 20);
  EXPECT_EQ(log.substr(0, first_line.size()), first_line);

  journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  EXPECT_TRUE(warnings.empty()) << Join(warnings);
  ASSERT_EQ(jobs.size(), 1u);
  const std::vector<JobFrameRecord>& frames = jobs[0].frames;
  EXPECT_EQ(FrameNumbers(frames), (std::vector<uint32_t>{5, 1, 3}));
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].bytes, 100u);
  EXPECT_EQ(frames[0].sha256, Sha('a'));
  EXPECT_EQ(frames[1].bytes, 4000000000000u);
  EXPECT_EQ(frames[1].sha256, Sha('d'));
  EXPECT_EQ(frames[2].bytes, 300u);
}

TEST_F(JobJournalTest, TornLastLineIsIgnoredWithAWarning) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  ASSERT_TRUE(journal->AppendFrame(kJobA, Frame(1, 10, 'a')).ok());
  ASSERT_TRUE(journal->AppendFrame(kJobA, Frame(2, 20, 'b')).ok());
  // SIGKILL in the middle of writing frame 3's line.
  const std::string log_path = JobPath(kJobA, "frames.log");
  WriteRaw(log_path, "3 30 " + Sha('c').substr(0, 17), /*append=*/true);

  journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(FrameNumbers(jobs[0].frames), (std::vector<uint32_t>{1, 2}));
  ASSERT_EQ(warnings.size(), 1u) << Join(warnings);
  EXPECT_NE(warnings[0].find(log_path + ":3"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("no newline"), std::string::npos) << warnings[0];

  // The resumed daemon appends after the fragment: the new line stays whole and the fragment
  // becomes a malformed line of its own.
  ASSERT_TRUE(journal->AppendFrame(kJobA, Frame(4, 40, 'd')).ok());
  warnings.clear();
  jobs = journal->LoadJobs(&warnings);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(FrameNumbers(jobs[0].frames), (std::vector<uint32_t>{1, 2, 4}));
  EXPECT_EQ(jobs[0].frames.back().sha256, Sha('d'));
  ASSERT_EQ(warnings.size(), 1u) << Join(warnings);
  EXPECT_NE(warnings[0].find("malformed"), std::string::npos) << warnings[0];
}

TEST_F(JobJournalTest, ACompleteLookingLastLineWithoutItsNewlineIsIgnored) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  ASSERT_TRUE(journal->AppendFrame(kJobA, Frame(1, 10, 'a')).ok());
  WriteRaw(JobPath(kJobA, "frames.log"), "2 20 " + Sha('b'), /*append=*/true);
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(FrameNumbers(jobs[0].frames), (std::vector<uint32_t>{1}));
  EXPECT_TRUE(AnyContains(warnings, "no newline")) << Join(warnings);
}

TEST_F(JobJournalTest, AFragmentIsNotGluedToTheNextLine) {
  // "1" torn from "17 ...", then "2 20 <sha>\n" appended: read together they would say frame
  // 12 is done.
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  WriteRaw(JobPath(kJobA, "frames.log"), "1");
  ASSERT_TRUE(journal->AppendFrame(kJobA, Frame(2, 20, 'b')).ok());
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(FrameNumbers(jobs[0].frames), (std::vector<uint32_t>{2}));
  EXPECT_EQ(jobs[0].frames[0].bytes, 20u);
  EXPECT_EQ(warnings.size(), 1u) << Join(warnings);  // the fragment, as a malformed line
}

TEST_F(JobJournalTest, MalformedLinesAreIgnoredWithWarnings) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  const std::string log_path = JobPath(kJobA, "frames.log");
  WriteRaw(log_path, "1 10 " + Sha('a') + "\n" +              // good
                         "\n" +                               // empty
                         "2 20\n" +                           // no sha
                         "x 30 " + Sha('c') + "\n" +          // frame not a number
                         "4 -1 " + Sha('d') + "\n" +          // negative size
                         "5 50 " + Sha('E') + "\n" +          // upper-case hex
                         "4294967296 1 " + Sha('f') + "\n" +  // frame past uint32
                         "6 60 " + Sha('b') + " x\n" +        // a fourth field
                         "7 70 " + Sha('7') + "\n");          // good
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(FrameNumbers(jobs[0].frames), (std::vector<uint32_t>{1, 7}));
  // Five reported line by line, the other two counted.
  ASSERT_EQ(warnings.size(), 6u) << Join(warnings);
  EXPECT_NE(warnings[0].find(log_path + ":2: malformed"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[5].find("2 more malformed lines"), std::string::npos) << warnings[5];
}

TEST_F(JobJournalTest, CorruptJobPbIsSkippedWithAWarningNamingIt) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobB, 2)).ok());
  // Field 1 (job_id) announces 127 bytes; 5 follow.
  WriteRaw(JobPath(kJobA, "job.pb"), std::string("\x0a\x7f", 2) + "short");
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].job.job_id(), kJobB);
  ASSERT_EQ(warnings.size(), 1u) << Join(warnings);
  EXPECT_NE(warnings[0].find(JobPath(kJobA, "job.pb")), std::string::npos) << warnings[0];
}

TEST_F(JobJournalTest, DirectoriesThatAreNotJobsAreSkippedWithWarnings) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  const std::string jobs_dir = state_ + "/jobs/";
  ASSERT_TRUE(fs::create_directory(jobs_dir + "not-a-job"));
  ASSERT_TRUE(fs::create_directory(jobs_dir + kJobB));  // no job.pb
  // A job.pb copied into another job's directory.
  const std::string other = "aaaaaaaaaaaaaaaa";
  ASSERT_TRUE(fs::create_directory(jobs_dir + other));
  fs::copy_file(JobPath(kJobA, "job.pb"), JobPath(other, "job.pb"));
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].job.job_id(), kJobA);
  EXPECT_EQ(warnings.size(), 3u) << Join(warnings);
  EXPECT_TRUE(AnyContains(warnings, jobs_dir + "not-a-job")) << Join(warnings);
  EXPECT_TRUE(AnyContains(warnings, JobPath(kJobB, "job.pb"))) << Join(warnings);
  EXPECT_TRUE(AnyContains(warnings, JobPath(other, "job.pb"))) << Join(warnings);
  // A null `warnings` is allowed.
  EXPECT_EQ(journal->LoadJobs(nullptr).size(), 1u);
}

TEST_F(JobJournalTest, InvalidJobIdsAreRefusedBeforeTheyBecomePaths) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  EXPECT_TRUE(JobJournal::ValidJobId(kJobA));
  for (const std::string id : {"../x", "ABCDEF0123456789", "0123", "", "0123456789abcdef0",
                               "0123456789abcdeg", "../../../../tmp/", "0123456789abcde/"}) {
    SCOPED_TRACE(id);
    EXPECT_FALSE(JobJournal::ValidJobId(id));
    EXPECT_TRUE(
        IsError(journal->SaveJob(MakeJob(id, 1)), absl::StatusCode::kInvalidArgument, {"job id"}));
    EXPECT_TRUE(IsError(journal->AppendFrame(id, Frame(1, 1, 'a')),
                        absl::StatusCode::kInvalidArgument, {"job id"}));
    EXPECT_TRUE(IsError(journal->RemoveJob(id), absl::StatusCode::kInvalidArgument, {"job id"}));
    EXPECT_EQ(journal->FramesDir(id), "");
  }
  EXPECT_EQ(Names(root_), (std::vector<std::string>{"state"}));
  EXPECT_TRUE(Names(state_ + "/jobs").empty());
}

TEST_F(JobJournalTest, AppendFrameNeedsASavedJobAndAWellFormedSha) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  EXPECT_TRUE(IsError(journal->AppendFrame(kJobA, Frame(1, 1, 'a')),
                      absl::StatusCode::kFailedPrecondition, {kJobA, "SaveJob"}));
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  JobFrameRecord bad = Frame(1, 1, 'a');
  bad.sha256 = "abc\n9 9 " + Sha('a');  // would forge a second line
  EXPECT_TRUE(
      IsError(journal->AppendFrame(kJobA, bad), absl::StatusCode::kInvalidArgument, {"sha256"}));
  bad.sha256 = Sha('A');
  EXPECT_TRUE(
      IsError(journal->AppendFrame(kJobA, bad), absl::StatusCode::kInvalidArgument, {"sha256"}));
  EXPECT_FALSE(fs::exists(JobPath(kJobA, "frames.log")));
}

TEST_F(JobJournalTest, ConcurrentAppendsAreAllKept) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  std::vector<std::thread> threads;
  for (uint32_t t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (uint32_t i = 0; i < 10; ++i)
        EXPECT_TRUE(journal->AppendFrame(kJobA, Frame(t * 100 + i, i, 'a' + t)).ok());
    });
  }
  for (std::thread& t : threads) t.join();
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  EXPECT_TRUE(warnings.empty()) << Join(warnings);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].frames.size(), 40u);
}

TEST_F(JobJournalTest, RemoveJobDeletesItsDirectory) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  ASSERT_TRUE(journal->SaveJob(MakeJob(kJobB, 2)).ok());
  ASSERT_TRUE(journal->AppendFrame(kJobA, Frame(1, 10, 'a')).ok());
  WriteRaw(journal->FramesDir(kJobA) + "/frame_00001.png", "png bytes");

  ASSERT_TRUE(journal->RemoveJob(kJobA).ok());
  EXPECT_EQ(Names(state_ + "/jobs"), (std::vector<std::string>{kJobB}));  // no leftover
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> jobs = journal->LoadJobs(&warnings);
  EXPECT_TRUE(warnings.empty()) << Join(warnings);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].job.job_id(), kJobB);
  EXPECT_TRUE(journal->RemoveJob(kJobA).ok());  // absent: OK
}

// ---------------------------------------------------------------------------------------------
// Scenes

TEST_F(JobJournalTest, SceneRoundTripWithNestedNames) {
  const std::string id = server::SceneIdOf(MakeScene());  // the real id (the archive checks it)
  const GltfSource source = MakeScene();
  {
    std::unique_ptr<JobJournal> journal = OpenJournal();
    ASSERT_NE(journal, nullptr);
    EXPECT_FALSE(journal->HasScene(id));
    EXPECT_EQ(journal->SceneBytes(id), 0u);
    absl::Status saved = journal->SaveScene(id, source);
    ASSERT_TRUE(saved.ok()) << saved;
    EXPECT_TRUE(journal->HasScene(id));
    EXPECT_TRUE(fs::is_regular_file(state_ + "/scenes/" + id + "/files/textures/a.png"));
  }
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  EXPECT_EQ(journal->ListScenes(), (std::vector<std::string>{id}));
  EXPECT_EQ(journal->SceneBytes(id), TotalBytes(source));
  absl::StatusOr<GltfSource> loaded = journal->LoadScene(id, 1 << 20);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  EXPECT_EQ(loaded->main_file, "scene.gltf");
  EXPECT_EQ(loaded->files, source.files);
  // Only the archive in scenes/: no temporary directory left.
  EXPECT_EQ(Names(state_ + "/scenes"), (std::vector<std::string>{id}));
}

TEST_F(JobJournalTest, SavingAnArchivedSceneAgainIsOkAndWritesNothing) {
  const std::string id = server::SceneIdOf(MakeScene());  // the real id (the archive checks it)
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveScene(id, MakeScene()).ok());
  GltfSource other = MakeScene();
  other.files["scene.gltf"] = Bytes("different");
  EXPECT_TRUE(journal->SaveScene(id, other).ok());
  absl::StatusOr<GltfSource> loaded = journal->LoadScene(id, 1 << 20);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  EXPECT_EQ(loaded->files, MakeScene().files);
  EXPECT_EQ(Names(state_ + "/scenes"), (std::vector<std::string>{id}));
}

TEST_F(JobJournalTest, InvalidSceneIdsAndFileNamesAreRefused) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  EXPECT_TRUE(JobJournal::ValidSceneId(SceneIdOf('0')));
  const GltfSource source = MakeScene();
  for (const std::string& id :
       {std::string("../x"), std::string("ABC"), std::string(""), std::string(64, 'A'),
        std::string(63, 'a'), std::string(65, 'a'), "../" + std::string(61, 'a')}) {
    SCOPED_TRACE(id);
    EXPECT_FALSE(JobJournal::ValidSceneId(id));
    EXPECT_TRUE(
        IsError(journal->SaveScene(id, source), absl::StatusCode::kInvalidArgument, {"scene id"}));
    EXPECT_TRUE(IsError(journal->LoadScene(id, 1 << 20).status(),
                        absl::StatusCode::kInvalidArgument, {"scene id"}));
    EXPECT_TRUE(
        IsError(journal->RemoveScene(id), absl::StatusCode::kInvalidArgument, {"scene id"}));
    EXPECT_FALSE(journal->HasScene(id));
    EXPECT_EQ(journal->SceneBytes(id), 0u);
  }

  const std::string id = SceneIdOf('7');
  for (const std::string name : {"../evil.bin", "/abs.bin", "a//b.bin", "a/./b.bin", "a\\b"}) {
    SCOPED_TRACE(name);
    GltfSource bad = MakeScene();
    bad.files[name] = Bytes("x");
    EXPECT_TRUE(IsError(journal->SaveScene(id, bad), absl::StatusCode::kInvalidArgument, {id}));
  }
  GltfSource no_main = MakeScene();
  no_main.main_file = "other.gltf";
  EXPECT_TRUE(
      IsError(journal->SaveScene(id, no_main), absl::StatusCode::kInvalidArgument, {"other.gltf"}));
  EXPECT_TRUE(Names(state_ + "/scenes").empty());
  EXPECT_EQ(Names(root_), (std::vector<std::string>{"state"}));
  EXPECT_EQ(Names(state_), (std::vector<std::string>{"jobs", "scenes"}));
}

TEST_F(JobJournalTest, LoadSceneKeepsTheByteLimit) {
  const std::string id = server::SceneIdOf(MakeScene());  // the real id (the archive checks it)
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  const GltfSource source = MakeScene();
  ASSERT_TRUE(journal->SaveScene(id, source).ok());
  const uint64_t total = TotalBytes(source);
  EXPECT_TRUE(journal->LoadScene(id, total).ok());
  EXPECT_TRUE(IsError(journal->LoadScene(id, total - 1).status(),
                      absl::StatusCode::kResourceExhausted, {id, std::to_string(total - 1)}));
  EXPECT_TRUE(
      IsError(journal->LoadScene(id, 0).status(), absl::StatusCode::kResourceExhausted, {id}));
}

TEST_F(JobJournalTest, RemoveSceneAndLoadingAnAbsentScene) {
  const std::string id = SceneIdOf('5');
  const std::string other = SceneIdOf('6');
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveScene(id, MakeScene()).ok());
  ASSERT_TRUE(journal->SaveScene(other, MakeScene()).ok());
  EXPECT_EQ(journal->ListScenes(), (std::vector<std::string>{id, other}));
  ASSERT_TRUE(journal->RemoveScene(id).ok());
  EXPECT_FALSE(journal->HasScene(id));
  EXPECT_EQ(journal->ListScenes(), (std::vector<std::string>{other}));
  EXPECT_EQ(Names(state_ + "/scenes"), (std::vector<std::string>{other}));  // no leftover
  EXPECT_TRUE(IsError(journal->LoadScene(id, 1 << 20).status(), absl::StatusCode::kNotFound, {id}));
  EXPECT_TRUE(journal->RemoveScene(id).ok());  // absent: OK
}

TEST_F(JobJournalTest, ADamagedSceneArchiveIsDataLoss) {
  const std::string id = SceneIdOf('5');
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  ASSERT_TRUE(journal->SaveScene(id, MakeScene()).ok());
  fs::remove(state_ + "/scenes/" + id + "/files/scene.gltf");
  EXPECT_TRUE(IsError(journal->LoadScene(id, 1 << 20).status(), absl::StatusCode::kDataLoss,
                      {id, "scene.gltf"}));
}

TEST_F(JobJournalTest, OpenRemovesWhatACrashLeftMidWay) {
  {
    std::unique_ptr<JobJournal> journal = OpenJournal();
    ASSERT_NE(journal, nullptr);
    ASSERT_TRUE(journal->SaveJob(MakeJob(kJobA, 1)).ok());
  }
  // A scene being archived, a job being deleted, a job.pb being replaced.
  const std::string scene_tmp = state_ + "/scenes/.tmp-new-" + SceneIdOf('5') + "-Ab12Cd";
  ASSERT_TRUE(fs::create_directories(scene_tmp + "/files/textures"));
  WriteRaw(scene_tmp + "/files/textures/a.png", "half a png");
  const std::string job_tmp = state_ + "/jobs/.tmp-del-" + std::string(kJobB) + "-Xy34Zw";
  ASSERT_TRUE(fs::create_directories(job_tmp + "/frames"));
  WriteRaw(job_tmp + "/job.pb", "x");
  WriteRaw(JobPath(kJobA, ".job.pb.tmp-123-0"), "half a job");

  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  EXPECT_FALSE(fs::exists(scene_tmp));
  EXPECT_FALSE(fs::exists(job_tmp));
  EXPECT_TRUE(Names(state_ + "/scenes").empty());
  EXPECT_EQ(Names(state_ + "/jobs"), (std::vector<std::string>{kJobA}));
  EXPECT_EQ(Names(state_ + "/jobs/" + kJobA), (std::vector<std::string>{"frames", "job.pb"}));
  EXPECT_TRUE(journal->ListScenes().empty());
  std::vector<std::string> warnings;
  EXPECT_EQ(journal->LoadJobs(&warnings).size(), 1u);
  EXPECT_TRUE(warnings.empty()) << Join(warnings);
}

TEST_F(JobJournalTest, OpenOnAPathUnderARegularFileFailsNamingIt) {
  const std::string file = root_ + "/plain_file";
  WriteRaw(file, "not a directory");
  const std::string dir = file + "/state";
  absl::StatusOr<std::unique_ptr<JobJournal>> journal = JobJournal::Open(dir);
  ASSERT_FALSE(journal.ok());
  EXPECT_NE(journal.status().message().find(dir), absl::string_view::npos) << journal.status();
  // The state directory itself a file.
  journal = JobJournal::Open(file);
  ASSERT_FALSE(journal.ok());
  EXPECT_NE(journal.status().message().find(file), absl::string_view::npos) << journal.status();
}

TEST_F(JobJournalTest, OpenCreatesPrivateDirectories) {
  std::unique_ptr<JobJournal> journal = OpenJournal();
  ASSERT_NE(journal, nullptr);
  for (const std::string& d : {state_, state_ + "/jobs", state_ + "/scenes"}) {
    SCOPED_TRACE(d);
    EXPECT_EQ(fs::status(d).permissions() & fs::perms::all, fs::perms::owner_all);
  }
  EXPECT_EQ(Names(state_), (std::vector<std::string>{"jobs", "scenes"}));  // no probe left
}

// ---------------------------------------------------------------------------------------------
// WriteFileAtomic, ReadWholeFile

TEST_F(JobJournalTest, WriteFileAtomicReplacesContentAndLeavesNoTemporaryFile) {
  const std::string path = root_ + "/out.bin";
  ASSERT_TRUE(WriteFileAtomic(path, "a first, longer content").ok());
  EXPECT_EQ(*ReadWholeFile(path, 1 << 20), "a first, longer content");
  const std::string binary("second\0\xff", 8);
  ASSERT_TRUE(WriteFileAtomic(path, binary).ok());
  EXPECT_EQ(*ReadWholeFile(path, 1 << 20), binary);
  ASSERT_TRUE(WriteFileAtomic(path, "").ok());
  EXPECT_EQ(*ReadWholeFile(path, 1 << 20), "");
  EXPECT_EQ(Names(root_), (std::vector<std::string>{"out.bin"}));

  const std::string missing = root_ + "/no_such_dir/out.bin";
  EXPECT_TRUE(IsError(WriteFileAtomic(missing, "x"), absl::StatusCode::kNotFound,
                      {missing, std::strerror(ENOENT)}));
  EXPECT_EQ(Names(root_), (std::vector<std::string>{"out.bin"}));
}

TEST_F(JobJournalTest, ReadWholeFileErrorsNameThePath) {
  const std::string path = root_ + "/ten.txt";
  WriteRaw(path, "0123456789");
  EXPECT_EQ(*ReadWholeFile(path, 10), "0123456789");
  EXPECT_TRUE(
      IsError(ReadWholeFile(path, 9).status(), absl::StatusCode::kResourceExhausted, {path, "9"}));
  const std::string missing = root_ + "/missing.txt";
  EXPECT_TRUE(IsError(ReadWholeFile(missing, 10).status(), absl::StatusCode::kNotFound, {missing}));
  EXPECT_TRUE(
      IsError(ReadWholeFile(root_, 10).status(), absl::StatusCode::kFailedPrecondition, {root_}));
}

}  // namespace
}  // namespace tessera::server
