// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Autosave and recovery (doc/autosave.h): when the Autosaver writes, that a clean save removes the
// recovery file, and that a process killed with SIGKILL after an autosave leaves a file that the
// next start lists and that loads to the same content.
#include "doc/autosave.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>

#include "doc/command.h"
#include "doc/document.h"

namespace spidarcad::app {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using modeling::ImplicitNode;

fs::path OutDir(const std::string& name) {
  const fs::path dir = fs::path(SPIDARCAD_TEST_OUTPUT_DIR) / ("autosave_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A document with a solid, a sculpt and a rigid part, made the same way in every process.
void Fill(Document* doc) {
  doc->Execute(edit::AddSolid("ball", ImplicitNode(modeling::SphereParams{0.04}, {}, "ball")));
  SculptMesh m;
  m.vertices.resize(3, 4);
  m.vertices << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0.25;
  m.triangles.resize(3, 2);
  m.triangles << 0, 1, 1, 2, 2, 3;
  doc->Execute(edit::AddSculpt("clay", m));
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translate(Eigen::Vector3d(0.01, 0.02, 0.03));
  doc->Execute(edit::AddRigidPart("lid", ImplicitNode(modeling::BoxParams{}, {}, "lid"), X));
}

nlohmann::json Content(const Document& doc) { return doc.ToJson(false); }

TEST(Autosaver, WritesOnlyWhenDirtyAndTheIntervalHasPassed) {
  const fs::path dir = OutDir("interval");
  const auto t0 = Autosaver::Clock::now();
  Autosaver saver(dir, 60s);
  Document doc;
  EXPECT_FALSE(saver.Tick(doc, t0 + 61s));  // clean
  Fill(&doc);
  EXPECT_FALSE(saver.Tick(doc, t0 + 59s));  // too early after construction
  EXPECT_TRUE(saver.Tick(doc, t0 + 61s));
  EXPECT_TRUE(fs::exists(saver.RecoveryPathFor(doc)));
  EXPECT_FALSE(saver.Tick(doc, t0 + 200s));  // nothing changed since
  doc.Execute(edit::RenameObject(doc.objects()[0].id, "sphere"));
  EXPECT_FALSE(saver.Tick(doc, t0 + 100s));  // changed, but only 39 s after the last autosave
  EXPECT_TRUE(saver.Tick(doc, t0 + 121s));
  ASSERT_EQ(ListRecoveryFiles(dir).size(), 1u);
  EXPECT_EQ(ListRecoveryFiles(dir)[0].original, "");  // untitled
  // A clean save removes the recovery file; the saved file itself is not a recovery file.
  const fs::path saved = dir / "saved" / "doc.json";
  fs::create_directories(saved.parent_path());
  doc.Save(saved.string());
  saver.Discard(doc);
  EXPECT_TRUE(ListRecoveryFiles(dir).empty());
  EXPECT_FALSE(saver.Tick(doc, t0 + 500s));  // clean again
  // Named documents get a recovery file of their own that names them.
  doc.Execute(edit::SetDescription("after save"));
  EXPECT_TRUE(saver.Tick(doc, t0 + 600s));
  const auto listed = ListRecoveryFiles(dir);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(listed[0].original, fs::absolute(saved).lexically_normal().string());
  EXPECT_NE(listed[0].path.filename().string().find(".spidarcad"), std::string::npos);
  // Closing discards it too.
  saver.Discard(doc);
  EXPECT_TRUE(ListRecoveryFiles(dir).empty());
}

TEST(Autosaver, RecoveryFileOfAKilledProcessIsListedAndLoadsToTheSameContent) {
  const fs::path dir = OutDir("killed");
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // The child: edit, autosave, tell the parent, then wait to be killed mid-session.
    ::close(ready[0]);
    Document doc;
    Fill(&doc);
    Autosaver saver(dir, 0s);
    const char ok = saver.Tick(doc) ? 'y' : 'n';
    (void)!::write(ready[1], &ok, 1);
    doc.Execute(edit::SetDescription("never autosaved"));  // lost with the process
    for (;;) ::pause();
  }
  ::close(ready[1]);
  char ok = 0;
  ASSERT_EQ(::read(ready[0], &ok, 1), 1);
  ::close(ready[0]);
  ASSERT_EQ(::kill(child, SIGKILL), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status));
  EXPECT_EQ(WTERMSIG(status), SIGKILL);
  ASSERT_EQ(ok, 'y');

  // The next start.
  const auto listed = ListRecoveryFiles(dir);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(listed[0].original, "");
  Document recovered;
  recovered.Load(listed[0].path.string());
  Document expected;
  Fill(&expected);
  EXPECT_EQ(Content(recovered), Content(expected));
  // No temporary file was left behind.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(Autosaver, DefaultDirectoryFollowsTheEnvironment) {
  const char* old = std::getenv("SPIDARCAD_RECOVERY_DIR");
  const std::string saved = old != nullptr ? old : "";
  const char* old_xdg = std::getenv("XDG_STATE_HOME");
  const std::string saved_xdg = old_xdg != nullptr ? old_xdg : "";
  const bool had_xdg = old_xdg != nullptr;
  ::unsetenv("SPIDARCAD_RECOVERY_DIR");
  ::setenv("XDG_STATE_HOME", "/xdg/state", 1);
  EXPECT_EQ(DefaultRecoveryDirectory(), fs::path("/xdg/state/spidarcad/recovery"));
  ::setenv("SPIDARCAD_RECOVERY_DIR", "/custom", 1);
  EXPECT_EQ(DefaultRecoveryDirectory(), fs::path("/custom"));
  if (old != nullptr) {
    ::setenv("SPIDARCAD_RECOVERY_DIR", saved.c_str(), 1);
  } else {
    ::unsetenv("SPIDARCAD_RECOVERY_DIR");
  }
  if (had_xdg) {
    ::setenv("XDG_STATE_HOME", saved_xdg.c_str(), 1);
  } else {
    ::unsetenv("XDG_STATE_HOME");
  }
}

}  // namespace
}  // namespace spidarcad::app
