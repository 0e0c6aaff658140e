// MathJax for pymdownx.arithmatex (generic mode). MathJax itself is the single-file SVG
// build vendored next to this file (vendor/mathjax: npm `mathjax` 3.2.2, es5/tex-svg-full.js,
// Apache-2.0): every TeX extension built in and glyphs drawn as SVG paths, so the equations
// render with no network and no web fonts.
window.MathJax = {
  tex: {
    inlineMath: [["\\(", "\\)"]],
    displayMath: [["\\[", "\\]"]],
    processEscapes: true,
    processEnvironments: true
  },
  svg: {
    fontCache: "global"
  },
  options: {
    ignoreHtmlClass: ".*|",
    processHtmlClass: "arithmatex"
  }
};

// Material's instant navigation swaps pages without reloading: typeset each new page
document$.subscribe(() => {
  if (!window.MathJax.typesetPromise) return;  // first page: MathJax typesets it at startup
  // the SVG output's global font cache (CHTML's clearCache does not exist on this build)
  const output = MathJax.startup.output;
  if (output.clearFontCache) output.clearFontCache();
  MathJax.typesetClear();
  MathJax.texReset();
  MathJax.typesetPromise();
});
