//! The documentation's own links: every relative link in README.md and the
//! Markdown under docs/, tools/ and fuzz/ names a file of the repository,
//! and every `#anchor` one of that file's headings (GitHub's rule: lower
//! case, spaces to hyphens, other punctuation dropped).

use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// The anchors of `text`'s headings (outside fenced code).
fn anchors(text: &str) -> HashSet<String> {
    let mut fenced = false;
    let mut out = HashSet::new();
    for line in text.lines() {
        if line.starts_with("```") {
            fenced = !fenced;
        }
        if fenced {
            continue;
        }
        let title = line.trim_start_matches('#');
        if title.len() == line.len() || !title.starts_with(' ') {
            continue;
        }
        out.insert(anchor(title.trim()));
    }
    out
}

fn anchor(title: &str) -> String {
    title
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, '-' | '_' | ' '))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The targets of `text`'s inline links `[..](target)` that are not URLs.
fn relative_links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("](") {
        rest = &rest[i + 2..];
        let Some(end) = rest.find([')', ' ', '\n']) else {
            break;
        };
        let target = &rest[..end];
        if !target.contains("://") && !target.starts_with("mailto:") && !target.is_empty() {
            out.push(target.to_string());
        }
    }
    out
}

fn markdown_files(root: &Path) -> Vec<PathBuf> {
    let mut files = vec![root.join("README.md")];
    for dir in ["docs", "tools", "fuzz"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir)) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.extension().is_some_and(|x| x == "md") {
                files.push(p);
            }
        }
    }
    files.sort();
    files
}

#[test]
fn relative_links_and_anchors_resolve() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files = markdown_files(root);
    assert!(files.len() > 3, "README.md and docs/*.md found: {files:?}");
    let mut broken = Vec::new();
    let mut checked = 0;
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        for link in relative_links(&text) {
            let (path, frag) = link.split_once('#').unwrap_or((&link, ""));
            let target = if path.is_empty() {
                file.clone()
            } else {
                file.parent().unwrap().join(path)
            };
            checked += 1;
            if !target.exists() {
                broken.push(format!("{}: {link}: no such file", file.display()));
                continue;
            }
            if !frag.is_empty() && target.extension().is_some_and(|x| x == "md") {
                let headings = anchors(&std::fs::read_to_string(&target).unwrap());
                if !headings.contains(frag) {
                    broken.push(format!("{}: {link}: no such heading", file.display()));
                }
            }
        }
    }
    assert!(checked > 10, "only {checked} links found");
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn anchors_follow_the_github_rule() {
    assert_eq!(
        anchor("Table I complete: floor plans, 6-DoF, SeDAR\\* and SIMP\\* (issue 20)"),
        "table-i-complete-floor-plans-6-dof-sedar-and-simp-issue-20"
    );
    assert_eq!(anchor("Serving: `omcl serve`"), "serving-omcl-serve");
    let text = "# A b\n```\n# not a heading\n```\n## C_d: e\n#nospace\n";
    let got = anchors(text);
    let want: HashSet<String> = ["a-b", "c_d-e"].map(String::from).into();
    assert_eq!(got, want);
    assert_eq!(
        relative_links("[x](docs/a.md#b) [y](https://e.org) [z](#c)"),
        ["docs/a.md#b", "#c"]
    );
}
