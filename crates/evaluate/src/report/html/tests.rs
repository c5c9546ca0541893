use super::super::fixture::{parameters, report};
use super::*;
use crate::table::ColumnGroup;

/// Every opened tag is closed in order (`<x/>` closes itself; `<!…>` is skipped); returns the
/// first problem.
fn check_tags(html: &str) -> Result<(), String> {
    let mut stack: Vec<String> = Vec::new();
    let mut rest = html;
    while let Some(start) = rest.find('<') {
        let end = rest[start..].find('>').ok_or("unterminated tag")? + start;
        let tag = &rest[start + 1..end];
        rest = &rest[end + 1..];
        if tag.starts_with('!') {
            continue;
        }
        if let Some(name) = tag.strip_prefix('/') {
            match stack.pop() {
                Some(open) if open == name => {}
                other => return Err(format!("</{name}> closes {other:?}")),
            }
        } else if !tag.ends_with('/') {
            let name: String = tag.chars().take_while(|c| !c.is_whitespace()).collect();
            stack.push(name);
        }
    }
    if stack.is_empty() {
        Ok(())
    } else {
        Err(format!("unclosed: {stack:?}"))
    }
}

#[test]
fn well_formed_self_contained_and_deterministic() {
    let r = report();
    let page = html(&r);
    check_tags(&page).unwrap();
    assert!(check_tags("<p><b></p></b>").is_err());
    assert!(check_tags("<p>").is_err());
    assert_eq!(page.matches("<svg").count(), parameters(&r));
    let svg_ns = "http://www.w3.org/2000/svg";
    assert_eq!(page.matches("http").count(), page.matches(svg_ns).count());
    assert!(!page.contains("<script") && !page.contains("<link") && !page.contains("<img"));
    assert_eq!(page, html(&r.clone()));
}

#[test]
fn shows_the_facts_and_marks_significant_cells() {
    let page = html(&report());
    assert!(page.contains("<title>RSA accuracy report: demo_scenario</title>"));
    assert!(page.contains("ExampleRSA 1.0 &lt;beta&gt;"));
    assert!(page.contains(&"ab".repeat(32)));
    assert!(page.contains("one-sided 95 % (τ = t(0.95; N−1))"));
    assert!(page.contains("<td>run-0007</td><td>no measured.json</td>"));
    assert_eq!(page.matches("<td class=\"pos").count(), 1);
    assert_eq!(page.matches("<td class=\"neg").count(), 1);
    assert!(
        page.contains("<td class=\"pos gs\"><strong>1.0 ± 0.15</strong> ▲</td>"),
        "{page}"
    );
    assert!(page.contains("<td class=\"neg gs\"><strong>−0.50 ± 0.075</strong> ▼</td>"));
    assert!(page.contains("<td>0.30 (N=1)</td>"));
    assert!(page.contains("<th class=\"gs\">x<sub>r</sub> (mm)</th>"));
    assert!(page.contains("Beyond the paper") && page.contains("ISO 5725-2"));
    assert!(page.contains("detector-det1 / s: no"));
}

/// The fixture's sources table widened to `groups` groups of three columns (the positive cell
/// first, then cells whose interval contains zero).
fn wide_report(groups: usize) -> Report {
    use crate::report::fixture::{NONE, POSITIVE, column};
    use crate::stats::Confidence;
    let mut r = report();
    let t = &mut r.tables[0];
    t.groups = (0..groups)
        .map(|g| ColumnGroup {
            label: format!("tube{g}"),
            columns: ["x_r", "y_c", "z_s"]
                .map(|c| column(&format!("{c}{g}"), c, "mm"))
                .to_vec(),
        })
        .collect();
    for row in &mut t.rows {
        row.cells = (0..groups * 3)
            .map(|k| {
                let res: &[f64] = if k == 0 { &POSITIVE } else { &NONE };
                Some(Cell::from_residuals(res, &Confidence::default()))
            })
            .collect();
    }
    r
}

#[test]
fn wide_tables_are_split_into_parts_that_fit_a_page() {
    let r = wide_report(5);
    let page = html(&r);
    check_tags(&page).unwrap();
    let section = &page[page.find("id=\"table-sources\"").unwrap()..];
    let section = &section[..section.find("</section>").unwrap()];
    // 15 columns, whole groups of 3, at most MAX_COLUMNS (6) per part: 6 + 6 + 3.
    assert_eq!(MAX_COLUMNS, 6);
    assert_eq!(section.matches("<table>").count(), 3);
    let heads: Vec<usize> = section
        .split("<table>")
        .skip(1)
        .map(|t| {
            t[..t.find("</thead>").unwrap()]
                .matches(" (mm)</th>")
                .count()
        })
        .collect();
    assert_eq!(heads, [6, 6, 3]);
    // Every column heading once, in order, and every part has the level and N columns.
    let mut last = 0;
    for g in 0..5 {
        for c in ["x_r", "y_c", "z_s"] {
            let (base, sub) = c.split_once('_').unwrap();
            let head = format!("{base}<sub>{sub}{g}</sub> (mm)</th>");
            assert_eq!(section.matches(&head).count(), 1, "{head}");
            let at = section.find(&head).unwrap();
            assert!(at > last, "{head} out of order");
            last = at;
        }
    }
    assert_eq!(section.matches("<th rowspan=\"2\">N</th>").count(), 3);
    // The cells follow their columns: the positive cell is the first column of the first part.
    let first_row = &section[section.find("<tbody>").unwrap()..];
    assert!(first_row.starts_with("<tbody>\n<tr><th>0.0%</th><td>5</td><td class=\"pos gs\">"));
    // A narrow table stays whole.
    assert_eq!(parts(&report().tables[0]).len(), 1);
}

#[test]
fn the_iso_table_is_split_with_table_and_parameter_repeated() {
    let page = html(&report());
    let iso = &page[page.find("<h3>ISO 5725-2").unwrap()..];
    let tables = iso.matches("<table class=\"iso\">").count();
    let fields = crate::report::iso::fields(&report().group_analyses[0]).len();
    assert_eq!(tables, (fields - 2).div_ceil(MAX_ISO_COLUMNS));
    assert!(tables >= 2);
    assert_eq!(
        iso.matches("<th>Table</th><th>Parameter</th>").count(),
        tables
    );
    for f in crate::report::iso::fields(&report().group_analyses[0]) {
        let head = format!("<th>{}</th>", esc(f.header));
        let expected = if matches!(f.header, "Table" | "Parameter") {
            tables
        } else {
            1
        };
        assert_eq!(iso.matches(&head).count(), expected, "{head}");
    }
}

#[test]
fn plots_name_their_detector_or_model_and_keep_their_caption() {
    let mut r = report();
    r.tables.push(Table {
        id: "phantom-femur".into(),
        caption: "Model femur".into(),
        ..r.tables[1].clone()
    });
    let page = html(&r);
    assert!(page.contains(">Detector det1 · orientation · α_r</text>"));
    assert!(page.contains(">Model femur · position · s</text>"));
    assert!(page.contains("<figcaption>Model femur · position · s (mm): trueness ± precision"));
    // The sources name themselves in their groups.
    assert!(page.contains(">tube1 · x_r</text>"));
    // Each plot and its caption in one figure, kept together on paper.
    assert_eq!(page.matches("<figure><svg").count(), parameters(&r));
    assert!(STYLE.contains("figure{display:inline-block;vertical-align:top;break-inside:avoid"));
    assert!(STYLE.contains("@media print{") && STYLE.contains("thead{display:table-header-group}"));
}

#[test]
fn mtpm_is_compared_with_the_threshold_not_marked_as_bias() {
    use crate::report::fixture::column;
    let mut r = report();
    // Model femur: 1.0 ± 0.15 (above 0.2 mm); model tibia: 0.03 ± 0.33 (upper end 0.36, above
    // too); with the threshold at 0.5 only the first is above.
    let mut mtpm = r.tables[0].clone();
    mtpm.id = "mtpm".into();
    mtpm.groups = ["femur", "tibia"]
        .map(|m| ColumnGroup {
            label: m.into(),
            columns: vec![column("MTPM", "\\mathrm{MTPM}", "mm")],
        })
        .to_vec();
    for row in &mut mtpm.rows {
        row.cells.truncate(2);
    }
    r.mtpm = Some(mtpm);
    r.mtpm_threshold_mm = 0.5;
    let page = html(&r);
    let section = &page[page.find("id=\"table-mtpm\"").unwrap()..];
    assert!(section.contains("compared with the threshold 0.5 mm"));
    assert!(section.contains("<td class=\"over gs\"><strong>1.0 ± 0.15</strong> &gt; 0.5</td>"));
    assert!(!section.contains('▲') && !section.contains("class=\"pos"));
    assert_eq!(section.matches("class=\"over").count(), 1);
    assert!(section.contains(">threshold 0.5</text>"));
    assert!(
        !section.contains("<path"),
        "no bias triangles in MTPM plots"
    );
    let md = crate::report::markdown(&r);
    assert!(md.contains("| **1.0 ± 0.15** > 0.5 |"), "{md}");
    assert!(!md[md.find("### MTPM").unwrap()..md.find("### ISO").unwrap()].contains('▲'));
    let tex = crate::report::latex(&r);
    let tex_mtpm = &tex[tex.rfind("\\begin{table*}").unwrap()..];
    assert!(tex_mtpm.contains("\\cellcolor{orange!25}$1.0 \\pm 0.15$~($>0.5$)"));
    assert!(!tex_mtpm.contains("red!25") && tex_mtpm.contains("threshold 0.5 mm"));
}
