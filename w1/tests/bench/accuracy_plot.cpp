#include "accuracy_plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iterator>

namespace spangle::plot {
namespace {

// Tableau 10, black first for the series a reader compares everything with.
constexpr const char* kColors[] = {"#000000", "#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f",
                                   "#b07aa1", "#9c755f", "#edc948", "#ff9da7", "#888888"};
constexpr int kColorCount = static_cast<int>(std::size(kColors));
constexpr int kMarkerCount = 7;
constexpr const char* kFloorColor = "#888888";

constexpr int kPanelHeight = 300;
constexpr double kMarginLeft = 64, kMarginRight = 14, kMarginTop = 30, kMarginBottom = 42;
constexpr double kLegendRow = 20;
constexpr int kLegendColumns = 3;

std::string escape(const std::string& s) {
    std::string out;
    for (char c : s) {
        if (c == '&')
            out += "&amp;";
        else if (c == '<')
            out += "&lt;";
        else if (c == '>')
            out += "&gt;";
        else
            out += c;
    }
    return out;
}

const char* color(int index) {
    return kColors[((index % kColorCount) + kColorCount) % kColorCount];
}

/** Marker `shape` in colour `col` centred at (x, y). */
void marker(std::string& out, int shape, int col, double x, double y) {
    const char* c = color(col);
    const double r = 3.6;
    switch (((shape % kMarkerCount) + kMarkerCount) % kMarkerCount) {
        case 0:
            fmt::format_to(std::back_inserter(out),
                           "<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"{:.1f}\" fill=\"{}\"/>\n", x, y,
                           r, c);
            break;
        case 1:
            fmt::format_to(std::back_inserter(out),
                           "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" "
                           "fill=\"{}\"/>\n",
                           x - r, y - r, 2 * r, 2 * r, c);
            break;
        case 2:
            fmt::format_to(
                std::back_inserter(out),
                "<path d=\"M{:.1f},{:.1f}L{:.1f},{:.1f}L{:.1f},{:.1f}Z\" fill=\"{}\"/>\n", x,
                y - 1.2 * r, x + 1.1 * r, y + 0.8 * r, x - 1.1 * r, y + 0.8 * r, c);
            break;
        case 3:
            fmt::format_to(std::back_inserter(out),
                           "<path d=\"M{:.1f},{:.1f}L{:.1f},{:.1f}L{:.1f},{:.1f}L{:.1f},{:.1f}Z\" "
                           "fill=\"{}\"/>\n",
                           x, y - 1.3 * r, x + 1.1 * r, y, x, y + 1.3 * r, x - 1.1 * r, y, c);
            break;
        case 4:
            fmt::format_to(
                std::back_inserter(out),
                "<path d=\"M{:.1f},{:.1f}L{:.1f},{:.1f}L{:.1f},{:.1f}Z\" fill=\"{}\"/>\n", x,
                y + 1.2 * r, x + 1.1 * r, y - 0.8 * r, x - 1.1 * r, y - 0.8 * r, c);
            break;
        case 5:
            fmt::format_to(
                std::back_inserter(out),
                "<path d=\"M{0:.1f},{1:.1f}L{2:.1f},{3:.1f}M{0:.1f},{3:.1f}L{2:.1f},{1:.1f}"
                "\" stroke=\"{4}\" stroke-width=\"2\"/>\n",
                x - r, y - r, x + r, y + r, c);
            break;
        default:
            fmt::format_to(
                std::back_inserter(out),
                "<path d=\"M{0:.1f},{1:.1f}L{2:.1f},{1:.1f}M{3:.1f},{4:.1f}L{3:.1f},{5:.1f}"
                "\" stroke=\"{6}\" stroke-width=\"2\"/>\n",
                x - 1.3 * r, y, x + 1.3 * r, x, y - 1.3 * r, y + 1.3 * r, c);
            break;
    }
}

/** "0.01" .. "1000" for decades -2..3, "10" with a superscript exponent otherwise. */
std::string decade_label(int k) {
    if (k >= 0 && k <= 3) return fmt::format("{}", static_cast<int>(std::pow(10.0, k)));
    if (k >= -2 && k < 0) return fmt::format("{:.{}f}", std::pow(10.0, k), -k);
    return fmt::format("10<tspan dy=\"-6\" font-size=\"9\">{}</tspan>", k);
}

/** Whole decades [lo, hi] holding every value; at least one decade. */
std::pair<int, int> decades(const std::vector<double>& values) {
    double lo = 0, hi = 0;
    bool any = false;
    for (double v : values) {
        if (!(v > 0) || !std::isfinite(v)) continue;
        lo = any ? std::min(lo, v) : v;
        hi = any ? std::max(hi, v) : v;
        any = true;
    }
    if (!any) return {0, 1};
    const int a = static_cast<int>(std::floor(std::log10(lo) + 1e-9));
    int b = static_cast<int>(std::ceil(std::log10(hi) - 1e-9));
    if (b <= a) b = a + 1;
    return {a, b};
}

bool usable(const std::pair<double, double>& p) {
    return p.first > 0 && p.second > 0 && std::isfinite(p.first) && std::isfinite(p.second);
}

void draw_panel(std::string& out, const Panel& panel, double x0, double y0, double w, double h) {
    std::vector<double> xs, ys;
    for (const Series& s : panel.series)
        for (const auto& p : s.points)
            if (usable(p)) {
                xs.push_back(p.first);
                ys.push_back(p.second);
            }
    if (panel.floor > 0) ys.push_back(panel.floor);
    // Plain names (lambdas below use them; clang 14 cannot capture structured bindings).
    const std::pair<int, int> xd = decades(xs), yd = decades(ys);
    const int xa = xd.first, xb = xd.second, ya = yd.first, yb = yd.second;
    const double left = x0 + kMarginLeft, right = x0 + w - kMarginRight;
    const double top = y0 + kMarginTop, bottom = y0 + h - kMarginBottom;
    const auto px = [&](double x) {
        return left + (std::log10(x) - xa) / (xb - xa) * (right - left);
    };
    const auto py = [&](double y) {
        return bottom - (std::log10(y) - ya) / (yb - ya) * (bottom - top);
    };
    auto& o = out;
    fmt::format_to(std::back_inserter(o),
                   "<text x=\"{:.1f}\" y=\"{:.1f}\" font-size=\"13\" font-weight=\"bold\" "
                   "text-anchor=\"middle\">{}</text>\n",
                   (left + right) / 2, y0 + 18, escape(panel.title));
    // Grid and ticks: a line and a label at every decade, short ticks at 2..9 times it.
    for (int k = xa; k <= xb; ++k) {
        const double x = px(std::pow(10.0, k));
        fmt::format_to(std::back_inserter(o),
                       "<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{0:.1f}\" y2=\"{2:.1f}\" "
                       "stroke=\"#dddddd\"/>\n<text x=\"{0:.1f}\" y=\"{3:.1f}\" font-size=\"11\" "
                       "text-anchor=\"middle\">{4}</text>\n",
                       x, top, bottom, bottom + 15, decade_label(k));
        for (int m = 2; m <= 9 && k < xb; ++m) {
            const double xm = px(m * std::pow(10.0, k));
            fmt::format_to(std::back_inserter(o),
                           "<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{0:.1f}\" y2=\"{2:.1f}\" "
                           "stroke=\"#444444\"/>\n",
                           xm, bottom, bottom - 4);
        }
    }
    for (int k = ya; k <= yb; ++k) {
        const double y = py(std::pow(10.0, k));
        fmt::format_to(std::back_inserter(o),
                       "<line x1=\"{1:.1f}\" y1=\"{0:.1f}\" x2=\"{2:.1f}\" y2=\"{0:.1f}\" "
                       "stroke=\"#dddddd\"/>\n<text x=\"{3:.1f}\" y=\"{4:.1f}\" font-size=\"11\" "
                       "text-anchor=\"end\">{5}</text>\n",
                       y, left, right, left - 5, y + 4, decade_label(k));
        for (int m = 2; m <= 9 && k < yb; ++m) {
            const double ym = py(m * std::pow(10.0, k));
            fmt::format_to(std::back_inserter(o),
                           "<line x1=\"{1:.1f}\" y1=\"{0:.1f}\" x2=\"{2:.1f}\" y2=\"{0:.1f}\" "
                           "stroke=\"#444444\"/>\n",
                           ym, left, left + 4);
        }
    }
    fmt::format_to(std::back_inserter(o),
                   "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" "
                   "fill=\"none\" stroke=\"#444444\"/>\n",
                   left, top, right - left, bottom - top);
    fmt::format_to(std::back_inserter(o),
                   "<text x=\"{:.1f}\" y=\"{:.1f}\" font-size=\"12\" "
                   "text-anchor=\"middle\">{}</text>\n",
                   (left + right) / 2, bottom + 33, escape(panel.x_label));
    fmt::format_to(std::back_inserter(o),
                   "<text transform=\"translate({:.1f},{:.1f}) rotate(-90)\" font-size=\"12\" "
                   "text-anchor=\"middle\">{}</text>\n",
                   x0 + 16, (top + bottom) / 2, escape(panel.y_label));
    if (panel.floor > 0)
        fmt::format_to(std::back_inserter(o),
                       "<line x1=\"{1:.1f}\" y1=\"{0:.1f}\" x2=\"{2:.1f}\" y2=\"{0:.1f}\" "
                       "stroke=\"{3}\" stroke-width=\"1.5\" stroke-dasharray=\"2,3\"/>\n",
                       py(panel.floor), left, right, kFloorColor);
    for (const Series& s : panel.series) {
        std::vector<std::pair<double, double>> pts;
        for (const auto& p : s.points)
            if (usable(p)) pts.emplace_back(px(p.first), py(p.second));
        if (s.line && pts.size() > 1) {
            std::string d;
            for (const auto& [x, y] : pts)
                fmt::format_to(std::back_inserter(d), "{:.1f},{:.1f} ", x, y);
            fmt::format_to(std::back_inserter(o),
                           "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" "
                           "stroke-width=\"{}\"{}/>\n",
                           d, color(s.color), s.color == 0 ? 2.2 : 1.5,
                           s.dashed ? " stroke-dasharray=\"6,3\"" : "");
        }
        for (const auto& [x, y] : pts) marker(o, s.marker, s.color, x, y);
    }
}

}  // namespace

std::string svg(const std::vector<Panel>& panels, int columns, int width) {
    columns = std::max(columns, 1);
    const int rows = (static_cast<int>(panels.size()) + columns - 1) / columns;
    const double panel_w = static_cast<double>(width) / columns;

    // The legend: each distinct label once, in order of first appearance.
    struct Entry {
        std::string label;
        int color, marker;
        bool line, dashed, floor;
    };
    std::vector<Entry> legend;
    const auto add = [&](const Entry& e) {
        for (const Entry& l : legend)
            if (l.label == e.label) return;
        legend.push_back(e);
    };
    for (const Panel& p : panels) {
        for (const Series& s : p.series) add({s.label, s.color, s.marker, s.line, s.dashed, false});
        if (p.floor > 0) add({p.floor_label, 0, 0, true, false, true});
    }
    const int legend_rows = (static_cast<int>(legend.size()) + kLegendColumns - 1) / kLegendColumns;
    const double legend_top = rows * kPanelHeight + 10.0;
    const double height = legend_top + legend_rows * kLegendRow + 10.0;

    std::string out;
    fmt::format_to(std::back_inserter(out),
                   "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1:.0f}\" "
                   "viewBox=\"0 0 {0} {1:.0f}\" font-family=\"DejaVu Sans, Arial, sans-serif\">\n"
                   "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
                   width, height);
    for (std::size_t i = 0; i < panels.size(); ++i) {
        const int col = static_cast<int>(i) % columns, row = static_cast<int>(i) / columns;
        draw_panel(out, panels[i], col * panel_w, row * kPanelHeight, panel_w, kPanelHeight);
    }
    const double column_w = (width - 2 * kMarginLeft) / kLegendColumns;
    for (std::size_t i = 0; i < legend.size(); ++i) {
        const Entry& e = legend[i];
        const double x = kMarginLeft + static_cast<double>(i % kLegendColumns) * column_w;
        const double y = legend_top + static_cast<double>(i / kLegendColumns) * kLegendRow + 8;
        if (e.floor)
            fmt::format_to(std::back_inserter(out),
                           "<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" "
                           "stroke=\"{}\" stroke-width=\"1.5\" stroke-dasharray=\"2,3\"/>\n",
                           x, y, x + 28, y, kFloorColor);
        else if (e.line)
            fmt::format_to(std::back_inserter(out),
                           "<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" "
                           "stroke=\"{}\" stroke-width=\"1.5\"{}/>\n",
                           x, y, x + 28, y, color(e.color),
                           e.dashed ? " stroke-dasharray=\"6,3\"" : "");
        if (!e.floor) marker(out, e.marker, e.color, x + 14, y);
        fmt::format_to(std::back_inserter(out),
                       "<text x=\"{:.1f}\" y=\"{:.1f}\" font-size=\"12\">{}</text>\n", x + 36,
                       y + 4, escape(e.label));
    }
    out += "</svg>\n";
    return out;
}

}  // namespace spangle::plot
