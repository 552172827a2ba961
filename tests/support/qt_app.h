#pragma once
/// @file
/// One QApplication for a GoogleTest binary of Qt widget tests, on the offscreen platform
/// unless the environment chose one (the Xvfb test sets DISPLAY and QT_QPA_PLATFORM=xcb).

#include <QApplication>
#include <QTest>
#include <cstdlib>

namespace costume::testing {

inline QApplication& TestApp() {
  static int argc = 1;
  static char name[] = "frontend_test";
  static char* argv[] = {name, nullptr};
  if (!std::getenv("QT_QPA_PLATFORM")) setenv("QT_QPA_PLATFORM", "offscreen", 1);
  static QApplication* app = new QApplication(argc, argv);
  return *app;
}

/// Processes Qt events until `condition()` holds or `timeout_ms` pass; returns whether it
/// holds. Use it inside ASSERT_TRUE or EXPECT_TRUE, never QtTest's QTRY_*, QVERIFY or
/// QCOMPARE: outside a QtTest run those only return from the test function when they fail
/// (after waiting twice the timeout more), and GoogleTest counts that as a pass.
template <typename Condition>
bool WaitFor(Condition condition, int timeout_ms) {
  return QTest::qWaitFor(condition, timeout_ms);
}

}  // namespace costume::testing
