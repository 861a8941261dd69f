//! Every relative link of the manual resolves: README.md, every `docs/**/*.md`,
//! plugins/README.md and every `deploy/**/README.md`. A link `[text](path)`,
//! `[text](path#anchor)`, `[text](#anchor)` or a reference `[name]: path` must name a file
//! or folder of the repository and, into a Markdown page, one of that page's headings by
//! GitHub's anchor rules (lower-case; spaces to `-`; punctuation but `-` and `_` dropped;
//! a repeated heading gets `-1`, `-2`, …). External links (`http://`, `https://`,
//! `mailto:`, any other scheme) are not followed. Links in fenced code blocks and code
//! spans are not links (GitHub renders none there) and are skipped. Plain string
//! scanning, no Markdown parser: what this reads is the subset of Markdown the docs use.

use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};

/// What a link may point at.
enum Entry {
    /// A Markdown page: its text, whose headings are its anchors.
    Page(String),
    /// Any other file, or a folder: it exists, and its anchors (if any) are not checked.
    Other,
}

/// How the checker reads the repository: the entry at a repository-relative path.
type Lookup = dyn Fn(&Path) -> Option<Entry>;

/// What checking a set of pages found.
struct Report {
    /// Relative links checked (external ones not counted).
    checked: usize,
    /// Every broken link as `file:line: (target): why`.
    broken: Vec<String>,
}

/// GitHub's anchor for a heading's Markdown text: its rendered text (a link's URL and the
/// code spans' backticks dropped), lower-cased, every character but letters, digits,
/// spaces, `-` and `_` dropped, each space made a `-`.
fn slug(heading: &str) -> String {
    drop_link_urls(heading)
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// `text` with the `(url)` of every `[label](url)` removed: what a heading renders as.
fn drop_link_urls(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(i) = rest.find("](") {
        out.push_str(&rest[..=i]);
        match rest[i + 2..].find(')') {
            Some(j) => rest = &rest[i + 2 + j + 1..],
            None => {
                rest = &rest[i + 1..];
                break;
            }
        }
    }
    out.push_str(rest);
    out
}

/// `page` with every line of a fenced code block (its fences included) blanked, so that
/// line numbers still count from the top of the page.
fn without_fences(page: &str) -> String {
    let mut fence: Option<(char, usize)> = None;
    let mut out = String::with_capacity(page.len());
    for line in page.lines() {
        let trimmed = line.trim_start();
        let run = |c: char| trimmed.chars().take_while(|&x| x == c).count();
        match fence {
            Some((c, n)) if run(c) >= n && trimmed[run(c)..].trim().is_empty() => fence = None,
            Some(_) => {}
            None if run('`') >= 3 => fence = Some(('`', run('`'))),
            None if run('~') >= 3 => fence = Some(('~', run('~'))),
            None => out.push_str(line),
        }
        out.push('\n');
    }
    out
}

/// `text` with every code span blanked to spaces, newlines kept: within each block of
/// non-blank lines, a run of backticks up to the next run of as many. A run with no closing
/// run in its block is literal text, as in CommonMark.
fn without_code_spans(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut block = String::new();
    for line in text.lines() {
        if line.trim().is_empty() {
            out.push_str(&blank_code_spans(&block));
            block.clear();
            out.push_str(line);
            out.push('\n');
        } else {
            block.push_str(line);
            block.push('\n');
        }
    }
    out.push_str(&blank_code_spans(&block));
    out
}

/// One block of text with its code spans blanked (see [`without_code_spans`]).
fn blank_code_spans(block: &str) -> String {
    let bytes = block.as_bytes();
    let run_at = |i: usize| bytes[i..].iter().take_while(|&&b| b == b'`').count();
    let mut out = bytes.to_vec();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] != b'`' {
            i += 1;
            continue;
        }
        let n = run_at(i);
        let mut j = i + n;
        let close = loop {
            match bytes[j..].iter().position(|&b| b == b'`') {
                None => break None,
                Some(k) if run_at(j + k) == n => break Some(j + k),
                Some(k) => j += k + run_at(j + k),
            }
        };
        let Some(close) = close else {
            i += n;
            continue;
        };
        for b in &mut out[i..close + n] {
            if *b != b'\n' {
                *b = b' ';
            }
        }
        i = close + n;
    }
    // Only ASCII bytes were replaced, by ASCII: still UTF-8.
    String::from_utf8(out).expect("blanking code spans keeps UTF-8")
}

/// The text of an ATX heading line (`## Text ##`), or `None` for any other line.
fn atx_heading(line: &str) -> Option<&str> {
    let indent = line.len() - line.trim_start_matches(' ').len();
    let line = line.trim_start_matches(' ');
    let level = line.chars().take_while(|&c| c == '#').count();
    if indent > 3 || !(1..=6).contains(&level) {
        return None;
    }
    let rest = &line[level..];
    if !(rest.is_empty() || rest.starts_with(' ') || rest.starts_with('\t')) {
        return None;
    }
    let text = rest.trim();
    let closing = text.trim_end_matches('#');
    Some(if closing.is_empty() || closing.ends_with(' ') {
        closing.trim_end()
    } else {
        text
    })
}

/// Every anchor of a page: its headings' slugs, a repeated one with `-1`, `-2`, ….
fn anchors(page: &str) -> Vec<String> {
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut out = Vec::new();
    for line in without_fences(page).lines() {
        let Some(text) = atx_heading(line) else {
            continue;
        };
        let base = slug(text);
        let n = seen.entry(base.clone()).or_insert(0);
        out.push(if *n == 0 {
            base.clone()
        } else {
            format!("{base}-{n}")
        });
        *n += 1;
    }
    out
}

/// Every link target of a page with its line (1-based): inline links and images
/// `[text](target)`, and reference definitions `[name]: target`; code is skipped.
fn links(page: &str) -> Vec<(usize, String)> {
    let prose = without_code_spans(&without_fences(page));
    let mut out = Vec::new();
    for (at, _) in prose.match_indices("](") {
        let rest = &prose[at + 2..];
        let end = rest
            .find(|c: char| c == ')' || c.is_whitespace())
            .unwrap_or(rest.len());
        let target = rest[..end].trim_start_matches('<').trim_end_matches('>');
        if !target.is_empty() {
            out.push((prose[..at].matches('\n').count() + 1, target.to_string()));
        }
    }
    for (i, line) in prose.lines().enumerate() {
        let line = line.trim_start();
        let Some(close) = line.strip_prefix('[').and_then(|l| l.find("]:")) else {
            continue;
        };
        if let Some(target) = line[close + 3..].split_whitespace().next() {
            out.push((i + 1, target.to_string()));
        }
    }
    out.sort_by_key(|(line, _)| *line);
    out
}

/// Whether a target leaves the repository's files: a URL with a scheme, or `mailto:`.
fn is_external(target: &str) -> bool {
    let scheme = target.split_once(':').map(|(s, _)| s);
    scheme.is_some_and(|s| {
        !s.is_empty()
            && !s.contains('/')
            && s.chars()
                .all(|c| c.is_ascii_alphanumeric() || "+.-".contains(c))
    })
}

/// The repository-relative path a link from page `from` names, or `None` when it climbs
/// out of the repository. A path starting with `/` is from the repository's root.
fn resolve(from: &Path, path: &str) -> Option<PathBuf> {
    let base = if path.starts_with('/') {
        Path::new("")
    } else {
        from.parent()?
    };
    let mut out = PathBuf::new();
    for part in base.join(path.trim_start_matches('/')).components() {
        match part {
            Component::Normal(p) => out.push(p),
            Component::ParentDir if out.pop() => {}
            Component::ParentDir => return None,
            _ => {}
        }
    }
    Some(out)
}

/// Why the link `target` on page `from` is broken, or `None` when it resolves.
fn problem(from: &Path, page: &str, target: &str, lookup: &Lookup) -> Option<String> {
    let (path, anchor) = match target.split_once('#') {
        Some((p, a)) => (p, Some(a)),
        None => (target, None),
    };
    let (name, text) = if path.is_empty() {
        (from.to_path_buf(), page.to_string())
    } else {
        let Some(name) = resolve(from, path) else {
            return Some("climbs out of the repository".into());
        };
        match lookup(&name) {
            None => return Some(format!("no file or folder {}", name.display())),
            Some(Entry::Other) => return None,
            Some(Entry::Page(text)) => (name, text),
        }
    };
    let anchor = anchor?;
    if anchors(&text).iter().any(|a| a == anchor) {
        return None;
    }
    Some(format!(
        "no heading with the anchor `{anchor}` in {}",
        name.display()
    ))
}

/// Checks every relative link of the pages `sources` (repository-relative paths).
fn check(sources: &[PathBuf], lookup: &Lookup) -> Report {
    let mut report = Report {
        checked: 0,
        broken: Vec::new(),
    };
    for source in sources {
        let Some(Entry::Page(page)) = lookup(source) else {
            report.broken.push(format!(
                "{}: not a readable Markdown page",
                source.display()
            ));
            continue;
        };
        for (line, target) in links(&page) {
            if is_external(&target) {
                continue;
            }
            report.checked += 1;
            if let Some(why) = problem(source, &page, &target, lookup) {
                report
                    .broken
                    .push(format!("{}:{line}: ({target}): {why}", source.display()));
            }
        }
    }
    report
}

/// The repository's root (this file is `tests/docs_links.rs` of the `skein` package in
/// `core/skein`).
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The entry at a repository-relative path, read from disk.
fn on_disk(path: &Path) -> Option<Entry> {
    let full = root().join(path);
    if full.is_dir() {
        return Some(Entry::Other);
    }
    if !full.is_file() {
        return None;
    }
    if full.extension().is_some_and(|e| e == "md") {
        return std::fs::read_to_string(&full).ok().map(Entry::Page);
    }
    Some(Entry::Other)
}

/// Every file under the repository-relative folder `dir` (recursively) that `keep` wants.
fn files_under(dir: &Path, keep: &dyn Fn(&Path) -> bool, out: &mut Vec<PathBuf>) {
    let Ok(listing) = std::fs::read_dir(root().join(dir)) else {
        return;
    };
    for item in listing.flatten() {
        let path = dir.join(item.file_name());
        if item.file_type().is_ok_and(|t| t.is_dir()) {
            files_under(&path, keep, out);
        } else if keep(&path) {
            out.push(path);
        }
    }
}

/// The manual's pages: README.md, docs/**/*.md, plugins/README.md, deploy/**/README.md.
fn manual_pages() -> Vec<PathBuf> {
    let mut pages = vec![
        PathBuf::from("README.md"),
        PathBuf::from("plugins/README.md"),
    ];
    files_under(
        Path::new("docs"),
        &|p| p.extension().is_some_and(|e| e == "md"),
        &mut pages,
    );
    files_under(
        Path::new("deploy"),
        &|p| p.ends_with("README.md"),
        &mut pages,
    );
    pages.sort();
    pages
}

#[test]
fn every_relative_link_of_the_manual_resolves() {
    let pages = manual_pages();
    assert!(
        pages.contains(&PathBuf::from("docs/README.md")),
        "no docs/README.md: {pages:?}"
    );
    let report = check(&pages, &on_disk);
    assert!(
        report.checked >= 50,
        "only {} relative links found in {pages:?}",
        report.checked
    );
    assert!(
        report.broken.is_empty(),
        "{} broken links in the manual:\n{}",
        report.broken.len(),
        report.broken.join("\n")
    );
}

#[test]
fn slugs_follow_github_rules() {
    assert_eq!(
        slug("Counter-UAS: hostile swarms"),
        "counter-uas-hostile-swarms"
    );
    assert_eq!(
        slug("The embedded simulator (`skein-sim`)"),
        "the-embedded-simulator-skein-sim"
    );
    assert_eq!(
        slug("0. The whole path, on a running swarm"),
        "0-the-whole-path-on-a-running-swarm"
    );
    assert_eq!(
        slug("The geofence: skein's, and the same on every PX4"),
        "the-geofence-skeins-and-the-same-on-every-px4"
    );
    assert_eq!(slug("`tf_parent_frame` and *TF*"), "tf_parent_frame-and-tf");
    assert_eq!(
        slug("See [the API](api.md#x) — twice"),
        "see-the-api--twice"
    );
    assert_eq!(slug("Ünïcode 2×"), "ünïcode-2");
    let page = "# Top\n## Top ##\n```sh\n# Top\n```\n    ## Top\n#NoHeading\n### Top\n";
    assert_eq!(anchors(page), ["top", "top-1", "top-2"]);
}

#[test]
fn broken_links_are_found_and_named() {
    let readme = "# Top\n\
        [good](docs/a.md#intro), ![a picture](docs/pic.png), [folder](docs/)\n\
        [gone](docs/missing.md) and [no such\nheading](docs/a.md#nowhere)\n\
        [self](#top), [self, wrong](#nope), [web](https://example.com/x.md#y), [mail](mailto:a@b)\n\
        `[code](not/checked.md)`, [up](../outside.md)\n\
        ```\n[fenced](not/checked/either.md)\n```\n\
        [ref]: docs/missing-too.md\n\
        A stray ` backtick\n\
        \n\
        [after it](docs/missing-3.md) ` and another\n";
    let a = "# Intro\n[back](../README.md#top), [back, wrong](../README.md#Top)\n";
    let pages: HashMap<PathBuf, String> = [("README.md", readme), ("docs/a.md", a)]
        .map(|(p, t)| (p.into(), t.into()))
        .into();
    let entry = move |p: &Path| match p.to_str() {
        Some("docs/pic.png" | "docs") => Some(Entry::Other),
        _ => pages.get(p).map(|t| Entry::Page(t.clone())),
    };
    let report = check(&["README.md".into(), "docs/a.md".into()], &entry);
    assert_eq!(
        report.broken,
        [
            "README.md:3: (docs/missing.md): no file or folder docs/missing.md",
            "README.md:4: (docs/a.md#nowhere): no heading with the anchor `nowhere` in docs/a.md",
            "README.md:5: (#nope): no heading with the anchor `nope` in README.md",
            "README.md:6: (../outside.md): climbs out of the repository",
            "README.md:10: (docs/missing-too.md): no file or folder docs/missing-too.md",
            "README.md:13: (docs/missing-3.md): no file or folder docs/missing-3.md",
            "docs/a.md:2: (../README.md#Top): no heading with the anchor `Top` in README.md",
        ]
    );
    assert_eq!(report.checked, 12);
}
