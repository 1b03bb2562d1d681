#pragma once
// Log-log line plots written as SVG text, for the accuracy report: a grid of panels, each a set
// of series (a polyline with markers, or markers alone), and one legend below them all.

#include <string>
#include <utility>
#include <vector>

namespace spangle::plot {

/** One series of a panel. Points with x or y <= 0 (or not finite) are left out. */
struct Series {
    std::string label;                              ///< legend text; equal labels share one entry
    std::vector<std::pair<double, double>> points;  ///< (x, y) in data units, drawn in order
    int color = 0;        ///< index into the palette (wraps): 0 black, then Tableau 10, grey last
    int marker = 0;       ///< circle, square, triangle, diamond, inverted triangle, x, + (wraps)
    bool line = true;     ///< false: markers only
    bool dashed = false;  ///< a dashed polyline
};

/** One log-log panel. */
struct Panel {
    std::string title;
    std::string x_label, y_label;
    std::vector<Series> series;
    double floor = 0;         ///< > 0: a dashed grey horizontal line at this y
    std::string floor_label;  ///< its legend text
};

/** The SVG document: `panels` in rows of `columns`, `width` pixels wide, the legend below.
 *  Axes span whole decades around the data of each panel. */
std::string svg(const std::vector<Panel>& panels, int columns, int width);

}  // namespace spangle::plot
