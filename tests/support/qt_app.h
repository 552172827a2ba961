#pragma once
/// @file
/// One QApplication for a GoogleTest binary of Qt widget tests, on the offscreen platform
/// unless the environment chose one (the Xvfb test sets DISPLAY and QT_QPA_PLATFORM=xcb).

#include <QApplication>
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

}  // namespace costume::testing
