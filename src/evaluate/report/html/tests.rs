use super::super::fixture::{parameters, report};
use super::*;

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
