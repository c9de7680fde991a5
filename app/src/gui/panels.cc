// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/panels.h"

#include <imgui.h>

#include <algorithm>
#include <cmath>

#include "gui/colour_map.h"
#include "gui/device_view.h"
#include "scene/grip_control.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/tension.h"

namespace spidarcad::app {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

ImU32 ToImColour(const Rgb& rgb, float alpha = 1.0f) {
  return ImGui::ColorConvertFloat4ToU32(ImVec4(
      static_cast<float>(rgb[0]), static_cast<float>(rgb[1]), static_cast<float>(rgb[2]), alpha));
}

const char* TensionStatusText(haptics::TensionStatus status) {
  switch (status) {
    case haptics::TensionStatus::kOk:
      return "ok";
    case haptics::TensionStatus::kSaturated:
      return "saturated";
    case haptics::TensionStatus::kInvalidInput:
      return "invalid input";
    case haptics::TensionStatus::kNotConverged:
      return "not converged";
  }
  return "?";
}

// A horizontal bar of fraction t in [0, 1] filled with `colour`, `height` pixels tall.
void Bar(double t, ImU32 colour, float width, float height) {
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const ImVec2 p = ImGui::GetCursorScreenPos();
  const float y0 = p.y + 0.5f * (ImGui::GetTextLineHeight() - height);
  draw->AddRectFilled(ImVec2(p.x, y0), ImVec2(p.x + width, y0 + height),
                      IM_COL32(225, 228, 234, 255), 2.0f);
  const float fill = width * static_cast<float>(std::clamp(std::isnan(t) ? 0.0 : t, 0.0, 1.0));
  draw->AddRectFilled(ImVec2(p.x, y0), ImVec2(p.x + fill, y0 + height), colour, 2.0f);
  draw->AddRect(ImVec2(p.x, y0), ImVec2(p.x + width, y0 + height), IM_COL32(150, 155, 165, 255),
                2.0f);
  ImGui::Dummy(ImVec2(width, ImGui::GetTextLineHeight()));
}

// The colour legend: the map from tau_min to tau_max with ticks.
void Legend(double tau_min, double tau_max, float width) {
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const ImVec2 p = ImGui::GetCursorScreenPos();
  const float h = 12.0f;
  const int n = 3;
  for (int k = 0; k < n; ++k) {
    const float x0 = p.x + width * k / n, x1 = p.x + width * (k + 1) / n;
    const ImU32 c0 = ToImColour(kTensionColourStops[k]);
    const ImU32 c1 = ToImColour(kTensionColourStops[k + 1]);
    draw->AddRectFilledMultiColor(ImVec2(x0, p.y), ImVec2(x1, p.y + h), c0, c1, c1, c0);
  }
  draw->AddRect(p, ImVec2(p.x + width, p.y + h), IM_COL32(120, 125, 135, 255));
  ImGui::Dummy(ImVec2(width, h + 2.0f));
  const int ticks = 5;
  char text[32];
  for (int k = 0; k < ticks; ++k) {
    const double v = tau_min + (tau_max - tau_min) * k / (ticks - 1);
    std::snprintf(text, sizeof(text), "%.1f", v);
    const float tw = ImGui::CalcTextSize(text).x;
    const float x = p.x + width * k / (ticks - 1) -
                    (k == 0           ? 0.0f
                     : k == ticks - 1 ? tw
                                      : 0.5f * tw);
    draw->AddLine(ImVec2(p.x + width * k / (ticks - 1), p.y + h),
                  ImVec2(p.x + width * k / (ticks - 1), p.y + h + 3.0f),
                  IM_COL32(90, 95, 105, 255));
    draw->AddText(ImVec2(x, p.y + h + 3.0f), ImGui::GetColorU32(ImGuiCol_Text), text);
  }
  ImGui::Dummy(ImVec2(width, ImGui::GetTextLineHeight() + 2.0f));
}

void Vec3Row(const char* label, const Eigen::Vector3d& v, double scale, const char* format,
             const char* unit) {
  ImGui::TableNextRow();
  ImGui::TableSetColumnIndex(0);
  ImGui::TextUnformatted(label);
  for (int k = 0; k < 3; ++k) {
    ImGui::TableSetColumnIndex(k + 1);
    ImGui::Text(format, v[k] * scale);
  }
  ImGui::TableSetColumnIndex(4);
  ImGui::TextDisabled("%s", unit);
}

bool BeginVecTable(const char* id, const char* c1, const char* c2, const char* c3) {
  if (!ImGui::BeginTable(id, 5, ImGuiTableFlags_SizingStretchProp | ImGuiTableFlags_RowBg)) {
    return false;
  }
  ImGui::TableSetupColumn("", ImGuiTableColumnFlags_WidthFixed, 70.0f);
  ImGui::TableSetupColumn(c1);
  ImGui::TableSetupColumn(c2);
  ImGui::TableSetupColumn(c3);
  ImGui::TableSetupColumn("", ImGuiTableColumnFlags_WidthFixed, 42.0f);
  ImGui::TableHeadersRow();
  return true;
}

}  // namespace

void ApplyPanelStyle() {
  ImGui::StyleColorsLight();
  ImGuiStyle& style = ImGui::GetStyle();
  style.WindowRounding = 0.0f;
  style.FrameRounding = 3.0f;
  style.GrabRounding = 3.0f;
  style.WindowBorderSize = 1.0f;
  style.ItemSpacing = ImVec2(6.0f, 4.0f);
  // With the 14.5 px font: 21 px frames, so the menu bar and title bars (the docked layout's
  // edges) fall on whole pixels.
  style.FramePadding.y = 3.25f;
  style.CellPadding = ImVec2(4.0f, 1.0f);
  ImVec4* c = style.Colors;
  c[ImGuiCol_WindowBg] = ImVec4(0.965f, 0.968f, 0.975f, 1.0f);
  c[ImGuiCol_Header] = ImVec4(0.80f, 0.85f, 0.93f, 1.0f);
  c[ImGuiCol_HeaderHovered] = ImVec4(0.72f, 0.80f, 0.93f, 1.0f);
  c[ImGuiCol_HeaderActive] = ImVec4(0.62f, 0.73f, 0.92f, 1.0f);
  c[ImGuiCol_TableRowBgAlt] = ImVec4(0.0f, 0.0f, 0.0f, 0.035f);
  c[ImGuiCol_Border] = ImVec4(0.70f, 0.72f, 0.76f, 1.0f);
}

PanelActions DrawDeviceFigures(const DeviceFrame& frame, const PanelContext& context) {
  PanelActions actions;
  const haptics::SpidarGeometry& g = *context.geometry;
  const haptics::GripPose& pose = frame.measured_pose;

  ImGui::Text("SPIDAR-G  1 kHz haptic loop");
  ImGui::SameLine();
  ImGui::TextDisabled("%5.1f fps", context.fps);
  ImGui::SameLine();
  ImGui::TextDisabled("frame %.0f×%.0f×%.0f mm, poles 2d = %.0f mm", 2e3 * g.a, 2e3 * g.b,
                      2e3 * g.c, 2e3 * g.d);
  ImGui::PushTextWrapPos(0.0f);
  ImGui::TextDisabled("device: %s", frame.source.c_str());
  if (context.link != nullptr && context.link->has_driver) {
    // The driver's link: green when data flows, orange on errors, red when down (zero force).
    const RigLink& link = *context.link;
    const bool ok = link.status == haptics::DeviceStatus::kOk;
    const bool down = link.status == haptics::DeviceStatus::kNotConnected;
    const ImVec4 colour = ok     ? ImVec4(0.1f, 0.5f, 0.2f, 1.0f)
                          : down ? ImVec4(0.8f, 0.1f, 0.1f, 1.0f)
                                 : ImVec4(0.75f, 0.35f, 0.0f, 1.0f);
    ImGui::TextColored(colour, "link %s%s", DescribeLink(link).c_str(), ok ? "" : "; zero force");
    if (context.board_sim) {
      bool plugged = link.plugged;
      if (ImGui::Checkbox("board plugged in (simulated unplug)", &plugged)) {
        actions.board_plug = plugged ? 1 : -1;
      }
    }
  }
  if (context.real_hand) {
    ImGui::TextDisabled("the grip is your hand on the device: the mouse does not move it");
  }
  ImGui::PopTextWrapPos();

  // Pose.
  if (BeginVecTable("pose", "x | roll", "y | pitch", "z | yaw")) {
    Vec3Row("p0", pose.p0, 1e3, "%8.2f", "mm");
    Vec3Row("rotation", RollPitchYaw(pose.Rotation()), kRadToDeg, "%8.2f", "°");
    ImGui::EndTable();
  }
  ImGui::Text("grasp θ  %7.2f°", pose.Grasp() * kRadToDeg);
  ImGui::SameLine();
  const bool fk_ok = frame.fk_status == haptics::FkStatus::kOk;
  ImGui::TextColored(fk_ok ? ImVec4(0.1f, 0.5f, 0.2f, 1.0f) : ImVec4(0.8f, 0.1f, 0.1f, 1.0f),
                     "FK %s", haptics::FkStatusName(frame.fk_status));
  ImGui::SameLine();
  ImGui::TextDisabled("rms %.3f mm", frame.fk_residual * 1e3);
  if (!context.real_hand) {  // a real hand's true pose is unknown
    const double dp = (frame.true_pose.p0 - pose.p0).norm();
    const double dr = haptics::RotationAngleBetween(frame.true_pose.Rotation(), pose.Rotation());
    ImGui::SameLine();
    ImGui::TextDisabled("hand − measured: %.3f mm, %.3f°", dp * 1e3, dr * kRadToDeg);
  }

  // Wrench.
  if (BeginVecTable("wrench", "x", "y", "z")) {
    Vec3Row("f asked", frame.wrench.head<3>(), 1.0, "%7.3f", "N");
    Vec3Row("f shown", frame.achieved.head<3>(), 1.0, "%7.3f", "N");
    Vec3Row("m asked", frame.wrench.segment<3>(3), 1e3, "%7.1f", "N·mm");
    Vec3Row("m shown", frame.achieved.segment<3>(3), 1e3, "%7.1f", "N·mm");
    ImGui::EndTable();
  }
  ImGui::Text("grasp torque g  asked %6.1f  shown %6.1f N·mm", frame.wrench[6] * 1e3,
              frame.achieved[6] * 1e3);
  const bool ok = frame.tension_status == haptics::TensionStatus::kOk;
  ImGui::TextColored(ok ? ImVec4(0.1f, 0.5f, 0.2f, 1.0f) : ImVec4(0.75f, 0.35f, 0.0f, 1.0f),
                     "tension solve: %s", TensionStatusText(frame.tension_status));
  ImGui::SameLine();
  ImGui::TextDisabled("|f| %.2f N", frame.achieved.head<3>().norm());
  if (context.drag_mode[0] != '\0') {
    ImGui::SameLine();
    ImGui::TextDisabled("  %s", context.drag_mode);
  }
  return actions;
}

void DrawStringFigures(const DeviceFrame& frame, const PanelContext& context, float width) {
  const float bar_width = std::max(60.0f, width - 170.0f);
  if (ImGui::BeginTable("strings", 4, ImGuiTableFlags_SizingFixedFit | ImGuiTableFlags_RowBg)) {
    ImGui::TableSetupColumn("#", ImGuiTableColumnFlags_WidthFixed, 22.0f);
    ImGui::TableSetupColumn("l_i [mm]", ImGuiTableColumnFlags_WidthFixed, 70.0f);
    ImGui::TableSetupColumn("τ_i [N]", ImGuiTableColumnFlags_WidthFixed, 56.0f);
    ImGui::TableSetupColumn("tension", ImGuiTableColumnFlags_WidthFixed, bar_width);
    ImGui::TableHeadersRow();
    for (int i = 0; i < haptics::kNumStrings; ++i) {
      const double tau = frame.tensions[i];
      const Rgb rgb = TensionColour(tau, context.tau_min, context.tau_max);
      ImGui::TableNextRow();
      ImGui::TableSetColumnIndex(0);
      const double* pole = haptics::StringPole(i) == 0 ? kPole1Colour : kPole2Colour;
      ImGui::TextColored(ImVec4(pole[0], pole[1], pole[2], 1.0f), "%d", i + 1);
      ImGui::TableSetColumnIndex(1);
      ImGui::Text("%8.2f", frame.lengths[i] * 1e3);
      ImGui::TableSetColumnIndex(2);
      ImGui::Text("%6.2f", tau);
      ImGui::TableSetColumnIndex(3);
      Bar(tau / context.tau_max, ToImColour(rgb), bar_width, 10.0f);
    }
    ImGui::EndTable();
  }
  Legend(context.tau_min, context.tau_max, width - 20.0f);
  ImGui::TextColored(ImVec4(kPole1Colour[0], kPole1Colour[1], kPole1Colour[2], 1.0f),
                     "■ pole 1 (1–4)");
  ImGui::SameLine();
  ImGui::TextColored(ImVec4(kPole2Colour[0], kPole2Colour[1], kPole2Colour[2], 1.0f),
                     " ■ pole 2 (5–8)");
  ImGui::SameLine();
  ImGui::TextDisabled(" τ [N]");
}

bool DrawSpringControls(DemoFieldSettings* field) {
  bool changed = false;
  if (ImGui::Checkbox("springs to the device centre", &field->enabled)) changed = true;
  ImGui::PushItemWidth(150.0f);
  float kt = static_cast<float>(field->k_translation);
  if (ImGui::SliderFloat("k  [N/m]", &kt, 0.0f, 300.0f, "%.0f")) {
    field->k_translation = kt;
    changed = true;
  }
  float kr = static_cast<float>(field->k_rotation);
  if (ImGui::SliderFloat("k_rot [N·m/rad]", &kr, 0.0f, 1.0f, "%.2f")) {
    field->k_rotation = kr;
    changed = true;
  }
  float kg = static_cast<float>(field->k_grasp);
  if (ImGui::SliderFloat("k_grasp [N·m/rad]", &kg, 0.0f, 0.2f, "%.3f")) {
    field->k_grasp = kg;
    changed = true;
  }
  ImGui::PopItemWidth();
  return changed;
}

void DrawControlsHelp() {
  auto help = [](const char* input, const char* action) {
    ImGui::TextDisabled("%s", input);
    ImGui::SameLine(150.0f);
    ImGui::TextUnformatted(action);
  };
  help("left-drag grip", "move it in the view plane");
  help("right-drag", "rotate grip (shift: roll; or ctrl+left)");
  help("wheel or [ ]", "grasp angle 20°–160°");
  help("drag elsewhere", "orbit (or middle); ctrl+wheel zoom");
  help("click a solid", "select it in the tree");
  help("Enter or squeeze", "select the solid the grip touches");
  help("F", "fit the view to the selection (or the scene)");
  help("1  3  7  0", "front, right, top, iso view");
  help("R  C  Esc", "reset grip, reset camera, quit");
  help("Space", "emergency stop (zero force, latched)");
}

}  // namespace spidarcad::app
