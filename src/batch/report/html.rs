//! The library page's HTML: one static, offline page (styles and the sorting script
//! inline), a row per material, a marked row with its reason for a material left out.

use std::fmt::Write as _;

use super::{Entry, ReportOptions, image_names};
use crate::output::HTML_MARK;

/// Percent-encodes every byte outside RFC 3986's unreserved set.
pub(super) fn percent_encode(s: &str) -> String {
    let mut out = String::new();
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(b as char);
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    out
}

/// The inverse of [`percent_encode`] (a malformed escape is kept as it is).
pub(super) fn unescape_src(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = b
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (b[i], hex) {
            (b'%', Some(v)) => {
                out.push(v);
                i += 3;
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Escapes text for HTML content and quoted attribute values.
pub(super) fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:1.5em;color:#222}
table{border-collapse:collapse;width:100%}
th,td{border-bottom:1px solid #ddd;padding:.4em;vertical-align:top;text-align:left}
th button{font:inherit;font-weight:bold;background:none;border:0;padding:0;cursor:pointer}
th button::after{content:' \\2195';color:#888}
.refl{min-width:15em}
.sw{display:inline-block;margin:0 .4em .4em 0;text-align:center;font-size:.8em}
.sw span{display:block;width:3.2em;height:3.2em;border:1px solid #999}
.small{font-size:.85em;color:#555}
img{display:block}
.lobe{width:360px;height:auto}
.warn{font-size:.85em;color:#8a5a00}
.failure{color:#a00000}
";

/// Sorts the table's rows by the clicked column's `data-KEY` attribute of each row,
/// numerically for `y`; clicking again reverses the order.
const SCRIPT: &str = "'use strict';
document.querySelectorAll('th button[data-key]').forEach(function (b) {
  b.addEventListener('click', function () {
    var key = b.getAttribute('data-key');
    var th = b.parentElement;
    var asc = th.getAttribute('aria-sort') !== 'ascending';
    document.querySelectorAll('th[aria-sort]').forEach(function (h) { h.setAttribute('aria-sort', 'none'); });
    th.setAttribute('aria-sort', asc ? 'ascending' : 'descending');
    var body = document.getElementById('materials');
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (r1, r2) {
      var a = r1.getAttribute('data-' + key), c = r2.getAttribute('data-' + key);
      var d = key === 'y' ? parseFloat(a) - parseFloat(c) : (a < c ? -1 : a > c ? 1 : 0);
      return asc ? d : -d;
    });
    rows.forEach(function (r) { body.appendChild(r); });
  });
});
";

/// The page: a header saying what each column means and what the report spent, then one
/// row per material.
pub fn page_html(entries: &[Entry], opts: &ReportOptions) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "{HTML_MARK}\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>goniospec material library ({n} materials)</title>\n\
         <link rel=\"icon\" href=\"data:,\">\n<style>\n{STYLE}</style>\n</head>\n<body>\n\
         <h1>Material library: {n} materials{gone}</h1>\n",
        n = entries.len(),
        gone = match entries.iter().filter(|e| e.failure.is_some()).count() {
            0 => String::new(),
            k => format!(" ({k} left out, marked &#10007; with the reason)"),
        }
    );
    let _ = write!(
        h,
        "<p class=\"small\">Colour: the directional-hemispherical reflectance R(&lambda;) at the \
         incident angle shown, under CIE illuminant D65 with the CIE 1931 2&deg; observer, \
         displayed in sRGB; Y is the luminous reflectance (a perfect white has Y = 1). A swatch \
         marked &dagger; lies outside the sRGB gamut and is shown clipped. Lobe: f cos&theta;<sub>o</sub> \
         in the plane of incidence (1/sr) and the reflected colour over the hemisphere, at the \
         simulated incident angle nearest 30&deg;. Sphere: <code>goniospec render</code> of the \
         table BRDF at a small budget ({px}&times;{px} pixels, {spp} samples per pixel: expect \
         noise), light from &theta; = 50&deg;, &phi; = &minus;120&deg; and a constant environment. \
         Fit: <code>goniospec fit</code> (GGX, base, thin film) with its RMS reflectance error and \
         its largest CIE &Delta;E2000 over the incident angles. &#9888; marks a warning the \
         simulation gave (all of them in <code>out/NAME.warnings</code>); &#10007; a material \
         left out of the library, with the reason. Click a column's name to sort.</p>",
        px = opts.sphere_px,
        spp = opts.spp
    );
    h.push('\n');
    h.push_str(
        "<table>\n<thead>\n<tr>\
         <th aria-sort=\"none\"><button type=\"button\" data-key=\"name\">Material</button></th>\
         <th aria-sort=\"none\"><button type=\"button\" data-key=\"y\">Reflectance</button></th>\
         <th>Lobe</th><th>Sphere</th><th>Fit</th><th>Files</th></tr>\n</thead>\n\
         <tbody id=\"materials\">\n",
    );
    for e in entries {
        row_html(&mut h, e);
    }
    let _ = write!(
        h,
        "</tbody>\n</table>\n<script>\n{SCRIPT}</script>\n</body>\n</html>\n"
    );
    h
}

/// The most kinds of warning a row shows; the rest are counted, and all are in
/// `out/NAME.warnings`.
const SHOWN_WARNINGS: usize = 5;

fn row_html(h: &mut String, e: &Entry) {
    let [lobe, sphere, _] = image_names(&e.name);
    if let Some(why) = &e.failure {
        // A material left out: its row, marked, with the reason; sorted last by Y.
        let _ = write!(
            h,
            "<tr class=\"left-out\" data-name=\"{name}\" data-y=\"-1\">\n<td><strong>{name}</strong>\
             <div class=\"small\">sample {sample}</div></td>\n\
             <td colspan=\"5\" class=\"failure\">&#10007; left out of the library: {why}</td>\n</tr>\n",
            name = esc(&e.name),
            sample = esc(&e.sample),
            why = esc(why)
        );
        return;
    }
    let _ = write!(
        h,
        "<tr data-name=\"{name}\" data-y=\"{y:.6}\">\n<td><strong>{name}</strong>\
         <div class=\"small\">sample {sample}</div><div class=\"small\">{settings}</div>\
         <div class=\"small\">{methods}</div>",
        name = esc(&e.name),
        y = e.mean_y,
        sample = esc(&e.sample),
        settings = esc(&e.settings),
        methods = esc(&e.methods)
    );
    // One line per kind of warning (the same warning at other angles or cells counted
    // on it), so the one that matters is not lost among repeats.
    let groups = super::tidy::group_warnings(&e.warnings);
    for g in groups.iter().take(SHOWN_WARNINGS) {
        let _ = write!(h, "<div class=\"warn\">&#9888; {}</div>", esc(&g.line()));
    }
    if groups.len() > SHOWN_WARNINGS {
        let rest: usize = groups[SHOWN_WARNINGS..].iter().map(|g| g.count).sum();
        let _ = write!(
            h,
            "<div class=\"warn\">and {} more kinds of warning ({rest} warnings) in out/{}.warnings</div>",
            groups.len() - SHOWN_WARNINGS,
            esc(&e.name)
        );
    }
    h.push_str("</td>\n<td class=\"refl\">");
    for s in &e.swatches {
        let [r, g, b] = s.srgb8;
        let _ = write!(
            h,
            "<div class=\"sw\"><span style=\"background:#{r:02x}{g:02x}{b:02x}\" \
             title=\"XYZ {x:.4}, {y:.4}, {z:.4}{clip}\"></span>{t}&deg;: Y {y:.3}{mark}</div>",
            x = s.xyz[0],
            y = s.xyz[1],
            z = s.xyz[2],
            t = s.theta_i_deg,
            clip = if s.clipped {
                " (outside sRGB, clipped)"
            } else {
                ""
            },
            mark = if s.clipped { "&dagger;" } else { "" }
        );
    }
    let _ = write!(
        h,
        "<div class=\"small\">mean Y over the simulated angles {:.4}</div></td>",
        e.mean_y
    );
    h.push('\n');
    let _ = write!(
        h,
        "<td><img class=\"lobe\" src=\"{lobe}\" width=\"1200\" height=\"600\" \
         alt=\"lobe of {name} at {t} degrees\"><div class=\"small\">from {src}</div></td>\n\
         <td><img src=\"{sphere}\" alt=\"sphere of {name}\"></td>\n",
        lobe = percent_encode(&lobe),
        sphere = percent_encode(&sphere),
        name = esc(&e.name),
        t = e.lobe_theta_deg,
        src = esc(&e.brdf_source)
    );
    match &e.fit {
        Some(f) => {
            let _ = write!(
                h,
                "<td>GGX &alpha; {:.3}<br>base {}<br>film {}<br>RMS R error {:.2e}<br>\
                 &Delta;E2000 up to {:.2}",
                f.ggx_alpha,
                esc(&f.base),
                esc(&f.film),
                f.rms_reflectance_error,
                f.max_delta_e2000
            );
            for w in &f.warnings {
                let _ = write!(h, "<div class=\"small\">{}</div>", esc(w));
            }
            h.push_str("</td>\n");
        }
        None => h.push_str("<td>not fitted</td>\n"),
    }
    h.push_str("<td>");
    for (label, href) in &e.files {
        let _ = write!(h, "<a href=\"{}\">{}</a><br>", esc(href), esc(label));
    }
    h.push_str("</td>\n</tr>\n");
}
