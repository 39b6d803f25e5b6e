//! The repository's documentation stands alone: every relative link in every Markdown file resolves to a
//! file or folder inside the repository, and no file points outside it to the shared folder beside it.

use tests::repo::{files, root};

/// The targets of the inline links `[text](target)` in `text`, without titles and anchors.
fn link_targets(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("](") {
        rest = &rest[i + 2..];
        let Some(end) = rest.find(')') else { break };
        let target = rest[..end].split_whitespace().next().unwrap_or("");
        out.push(target.split('#').next().unwrap_or("").to_owned());
        rest = &rest[end..];
    }
    out
}

#[test]
fn every_relative_link_in_the_markdown_files_resolves_inside_the_repository() {
    let root = root();
    let mut all = Vec::new();
    files(&root, &mut all);
    let mut broken = Vec::new();
    let mut checked = 0;
    for md in all.iter().filter(|p| p.extension().is_some_and(|e| e == "md")) {
        let text = std::fs::read_to_string(md).expect("readable Markdown");
        for target in link_targets(&text) {
            if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            checked += 1;
            let resolved = md.parent().expect("a file has a folder").join(&target);
            let inside = resolved.canonicalize().is_ok_and(|p| p.starts_with(root.canonicalize().expect("root")));
            if !inside {
                broken.push(format!("{}: {target}", md.strip_prefix(&root).unwrap_or(md).display()));
            }
        }
    }
    assert!(checked > 10, "found only {checked} relative links: is the scan looking at the repository?");
    assert!(broken.is_empty(), "links that do not resolve inside the repository:\n{}", broken.join("\n"));
}

#[test]
fn nothing_in_the_repository_points_to_the_shared_folder_outside_it() {
    let root = root();
    let mut all = Vec::new();
    files(&root, &mut all);
    let needle = ["..", "/shared"].concat();
    let offenders: Vec<String> = all
        .iter()
        .filter(|p| std::fs::read_to_string(p).is_ok_and(|text| text.contains(&needle)))
        .map(|p| p.strip_prefix(&root).unwrap_or(p).display().to_string())
        .collect();
    assert!(offenders.is_empty(), "files that point outside the repository: {offenders:?}");
}
