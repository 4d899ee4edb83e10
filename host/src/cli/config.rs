//! `--config FILE` (TOML) for the commands that run the algorithm, and `riseg config
//! --print`.
//!
//! A settings file has up to three sections, each optional, each key optional:
//! `[core]` (riseg-core's [`Config`](riseg_core::Config)), `[segmenter]`
//! ([`SegmenterParams`](crate::segment::SegmenterParams)) and `[flow]`
//! ([`FlowParams`]). A key replaces its default; a missing key keeps it. Unknown
//! sections and keys, values of the wrong type and values out of range are errors naming
//! the file, the section and the key. The field names are those of the three structs,
//! and `riseg config --print` writes every key with its default and its doc (units are
//! in the names: `push_len_m`, `grow_tol_px`, `crease_soft_deg`).

use std::path::{Path, PathBuf};

use anyhow::{Context as _, anyhow, bail};
use serde::{Serialize, de::DeserializeOwned};

use crate::flow::{DisFlow, FlowParams};
pub use crate::rig::tracker::Settings;

/// The sections of a settings file, in the order `riseg config --print` writes them.
const SECTIONS: [&str; 3] = ["core", "segmenter", "flow"];

/// A parsed and checked settings file.
#[derive(Debug, Clone, Default)]
pub struct ConfigFile {
    /// The file's name as given, for error messages (empty without a file).
    name: String,
    /// The keys of `[flow]`, kept to apply over another preset ([`ConfigFile::flow_over`]).
    flow_keys: toml::Table,
    /// The settings: the defaults with the file's keys applied.
    settings: Settings,
}

impl ConfigFile {
    /// Reads and checks the settings file at `path`.
    ///
    /// # Errors
    /// The file cannot be read, is not TOML, or has an unknown section or key or a bad
    /// value; the message names the file, the section and the key.
    pub fn read(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading config file {}", path.display()))?;
        Self::parse(&path.display().to_string(), &text)
    }

    /// Parses and checks settings from `text`; `name` names the file in errors.
    ///
    /// # Errors
    /// As [`ConfigFile::read`], less reading.
    pub fn parse(name: &str, text: &str) -> anyhow::Result<Self> {
        let top: toml::Table = text.parse().map_err(|e| anyhow!("{name}: {e}"))?;
        let mut sections: [toml::Table; 3] = Default::default();
        for (key, value) in top {
            let Some(i) = SECTIONS.iter().position(|s| *s == key) else {
                bail!(
                    "{name}: unknown section or key `{key}` (the sections are [core], \
                     [segmenter] and [flow]; `riseg config --print` lists every key)"
                );
            };
            let toml::Value::Table(table) = value else {
                bail!("{name}: `{key}` must be a section, [{key}]");
            };
            sections[i] = table;
        }
        let [core_keys, segmenter_keys, flow_keys] = sections;
        let defaults = Settings::default();

        let core = overlay(name, "core", &defaults.core, &core_keys)?;
        if core.check().is_err() {
            // Config::check names no field: find a key that fails on its own.
            let culprit = core_keys.iter().find(|(key, value)| {
                let one = toml::Table::from_iter([((*key).clone(), (*value).clone())]);
                overlay(name, "core", &defaults.core, &one).is_ok_and(|c| c.check().is_err())
            });
            let what = culprit.map_or_else(
                || "these values together".to_owned(),
                |(key, value)| format!("{key} = {value}"),
            );
            bail!(
                "{name}: [core] {what}: out of range (riseg_core::Config::check: lengths \
                 finite and > 0, counts > 0, frame_min_side_m < frame_max_side_m, \
                 frame_min_sin in [0, 1), link_posterior in (0, 1), uncertain_from < \
                 certain_from, max_clusters in 2..=16 and <= kmeans_samples, \
                 depth_window_px <= 8)"
            );
        }
        let segmenter = overlay(name, "segmenter", &defaults.segmenter, &segmenter_keys)?;
        segmenter
            .check()
            .map_err(|e| anyhow!("{name}: [segmenter] {e}"))?;
        let mut file = Self {
            name: name.to_owned(),
            flow_keys,
            settings: Settings {
                core,
                segmenter,
                flow: defaults.flow,
            },
        };
        file.settings.flow = file.flow_over(defaults.flow)?;
        Ok(file)
    }

    /// The settings: the defaults with the file's keys applied.
    #[must_use]
    pub const fn settings(&self) -> Settings {
        self.settings
    }

    /// `[flow]` applied over `base` (the preset `riseg flow --preset` picked).
    ///
    /// # Errors
    /// A value of `[flow]` out of range on this base, naming the file.
    pub fn flow_over(&self, base: FlowParams) -> anyhow::Result<FlowParams> {
        let flow = overlay(&self.name, "flow", &base, &self.flow_keys)?;
        DisFlow::new(flow).map_err(|e| anyhow!("{}: [flow] {e}", self.name))?;
        Ok(flow)
    }

    /// The settings that differ from the defaults, `section.key = value`, for the log.
    fn changed(&self) -> Vec<String> {
        let (s, d) = (self.settings, Settings::default());
        let tables = |s: Settings| {
            [
                toml::Table::try_from(s.core),
                toml::Table::try_from(s.segmenter),
                toml::Table::try_from(s.flow),
            ]
            .map(Result::unwrap_or_default)
        };
        SECTIONS
            .iter()
            .zip(tables(s).into_iter().zip(tables(d)))
            .flat_map(|(section, (set, default))| {
                set.into_iter()
                    .filter(move |(k, v)| default.get(k) != Some(v))
                    .map(move |(k, v)| format!("{section}.{k} = {v}"))
            })
            .collect()
    }
}

/// `base` with the keys of `keys` replaced, one key at a time so an error names it.
fn overlay<T: Serialize + DeserializeOwned + Copy>(
    file: &str,
    section: &str,
    base: &T,
    keys: &toml::Table,
) -> anyhow::Result<T> {
    if keys.is_empty() {
        return Ok(*base);
    }
    let mut table = toml::Table::try_from(base)
        .with_context(|| format!("{file}: [{section}] defaults as TOML"))?;
    for (key, value) in keys {
        table.insert(key.clone(), value.clone());
        toml::Value::Table(table.clone())
            .try_into::<T>()
            .map_err(|e| anyhow!("{file}: [{section}] {key}: {}", e.message().trim()))?;
    }
    toml::Value::Table(table)
        .try_into::<T>()
        .map_err(|e| anyhow!("{file}: [{section}] {}", e.message().trim()))
}

/// `--config FILE` of the commands that run the algorithm.
#[derive(Debug, Clone, Default, clap::Args)]
pub(in crate::cli) struct ConfigArg {
    /// Settings file (TOML) with optional [core], [segmenter] and [flow] sections: each key
    /// replaces its default, a missing key keeps it. `riseg config --print` writes every
    /// key with its default, meaning and unit.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
}

impl From<Option<PathBuf>> for ConfigArg {
    fn from(config: Option<PathBuf>) -> Self {
        Self { config }
    }
}

impl ConfigArg {
    /// The file given, read and checked, or the defaults without `--config`.
    pub(in crate::cli) fn load(&self) -> anyhow::Result<ConfigFile> {
        let Some(path) = &self.config else {
            return Ok(ConfigFile::default());
        };
        let file = ConfigFile::read(path)?;
        let changed = file.changed();
        if changed.is_empty() {
            log::info!("config {}: the defaults", path.display());
        } else {
            log::info!("config {}: {}", path.display(), changed.join(", "));
        }
        Ok(file)
    }
}

/// `riseg config`.
#[derive(Debug, clap::Args)]
pub(in crate::cli) struct ConfigCmdArgs {
    /// Print every setting with its default value, meaning and unit, as a TOML file that
    /// `--config` reads.
    #[arg(long, required = true)]
    print: bool,
}

pub(in crate::cli) fn command(args: &ConfigCmdArgs) -> anyhow::Result<()> {
    if args.print {
        say!("{}", default_toml()?)?;
    }
    Ok(())
}

/// The default settings as a TOML file, each key after its doc.
///
/// # Errors
/// Only if a default cannot be written as TOML (a bug).
pub fn default_toml() -> anyhow::Result<String> {
    let d = Settings::default();
    let mut out = String::from(
        "# riseg settings, the defaults. `riseg demo|bench|run|eval|segment|flow --config\n\
         # FILE` reads a file like this one: every section and key is optional, a missing key keeps\n\
         # the default shown here, an unknown key or a bad value is an error. Units are in\n\
         # the names (_m metres, _m2 square metres, _px pixels, _deg degrees).\n",
    );
    section(
        &mut out,
        "core",
        "riseg-core's Config: the algorithm (the paper's defaults, Config::PAPER).",
        riseg_core::CONFIG_SOURCE,
        "Config",
        &toml::Table::try_from(d.core)?,
    );
    section(
        &mut out,
        "segmenter",
        "The built-in classical static segmenter (SegmenterParams). `riseg segment --seed`\n\
         replaces `seed`.",
        include_str!("../segment/params.rs"),
        "SegmenterParams",
        &toml::Table::try_from(d.segmenter)?,
    );
    section(
        &mut out,
        "flow",
        "The built-in DIS optical flow (FlowParams), preset \"medium\". `riseg flow` applies\n\
         these keys over its --preset.",
        include_str!("../flow/dis.rs"),
        "FlowParams",
        &toml::Table::try_from(d.flow)?,
    );
    Ok(out)
}

/// Appends `[name]`, its intro and every field of `struct_name` in `source` (doc comment,
/// then `key = default`); a field without a value (an unset `Option`) is commented out.
fn section(
    out: &mut String,
    name: &str,
    intro: &str,
    source: &str,
    struct_name: &str,
    values: &toml::Table,
) {
    out.push('\n');
    for line in intro.lines() {
        out.push_str("# ");
        out.push_str(line);
        out.push('\n');
    }
    out.push_str(&format!("[{name}]\n"));
    for field in field_docs(source, struct_name) {
        if let Some(heading) = &field.heading {
            out.push_str(&format!("\n# --- {heading} ---\n"));
        }
        out.push('\n');
        for line in wrap(&field.doc, 86) {
            out.push_str("# ");
            out.push_str(&line);
            out.push('\n');
        }
        match values.get(&field.name) {
            Some(value) => out.push_str(&format!("{} = {}\n", field.name, toml_value(value))),
            None => out.push_str(&format!("# {} = (unset)\n", field.name)),
        }
    }
}

/// A value as TOML, floats in the shortest form that reads back to the same `f32` (every
/// float setting is an `f32`).
fn toml_value(value: &toml::Value) -> String {
    match value {
        toml::Value::Float(f) => format!("{:?}", *f as f32),
        other => other.to_string(),
    }
}

/// One field of a struct, read from its source.
#[derive(Debug, Clone, PartialEq, Eq)]
struct FieldDoc {
    /// A `// --- Heading ---` comment just before the field, if any.
    heading: Option<String>,
    /// The field's name.
    name: String,
    /// Its doc comment as one paragraph, links reduced to their text.
    doc: String,
}

/// The fields of `pub struct struct_name` in `source` with their docs.
fn field_docs(source: &str, struct_name: &str) -> Vec<FieldDoc> {
    let start = format!("pub struct {struct_name} {{");
    let mut fields = Vec::new();
    let Some(at) = source.find(&start) else {
        return fields;
    };
    let (mut doc, mut heading) = (Vec::new(), None);
    for line in source[at + start.len()..].lines().map(str::trim) {
        if line == "}" {
            break;
        }
        if let Some(text) = line.strip_prefix("///") {
            doc.push(text.trim().to_owned());
        } else if let Some(text) = line.strip_prefix("// ---") {
            heading = Some(text.trim_matches(|c| c == '-' || c == ' ').to_owned());
        } else if let Some((name, _)) = line.strip_prefix("pub ").and_then(|l| l.split_once(':')) {
            fields.push(FieldDoc {
                heading: heading.take(),
                name: name.trim().to_owned(),
                doc: plain(&doc.join(" ")),
            });
            doc.clear();
        }
    }
    fields
}

/// `text` with rustdoc links (`[`a`]`, `[`a`](b)`) reduced to their text (`` `a` ``).
fn plain(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(open) = rest.find("[`") {
        out.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        let Some(close) = after.find("`]") else {
            out.push_str(&rest[open..]);
            return out;
        };
        out.push_str(&after[..=close]);
        rest = &after[close + 2..];
        if rest.starts_with('(') {
            rest = rest.find(')').map_or(rest, |end| &rest[end + 1..]);
        }
    }
    out.push_str(rest);
    out
}

/// `text` split into lines of at most `width` characters at spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > width {
            lines.push(core::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn printed_defaults_read_back_as_the_defaults() {
        let text = default_toml().unwrap();
        let file = ConfigFile::parse("defaults.toml", &text).unwrap();
        assert_eq!(file.settings(), Settings::default());
        assert!(file.flow_keys.contains_key("patch_stride_px"), "{text}");
        // Every key is written (the Option left unset as a comment) after its doc.
        let d = Settings::default();
        for (section, source, name, values) in [
            (
                "core",
                riseg_core::CONFIG_SOURCE,
                "Config",
                toml::Table::try_from(d.core).unwrap(),
            ),
            (
                "segmenter",
                include_str!("../segment/params.rs"),
                "SegmenterParams",
                toml::Table::try_from(d.segmenter).unwrap(),
            ),
            (
                "flow",
                include_str!("../flow/dis.rs"),
                "FlowParams",
                toml::Table::try_from(d.flow).unwrap(),
            ),
        ] {
            let fields = field_docs(source, name);
            for key in values.keys() {
                let field = fields.iter().find(|f| &f.name == key);
                assert!(
                    field.is_some_and(|f| !f.doc.is_empty()),
                    "[{section}] {key} has no doc"
                );
                assert!(text.contains(&format!("\n{key} = ")), "{key}");
            }
        }
        assert!(text.contains("\n# coarsest_level = (unset)\n"), "{text}");
        assert!(text.contains("\n# --- CreateFrames ---\n"), "{text}");
        assert!(text.contains("\npush_len_m = 0.02\n"), "{text}");
        assert!(!text.contains("[`"), "links left in the docs");
    }

    #[test]
    fn an_empty_file_is_the_defaults_and_one_key_changes_one_value() {
        let empty = ConfigFile::parse("empty.toml", "").unwrap();
        assert_eq!(empty.settings(), Settings::default());
        let file = ConfigFile::parse(
            "one.toml",
            "[core]\nmax_pushes = 1\n[segmenter]\nseed = 7\n[flow]\ncoarsest_level = 4\n",
        )
        .unwrap();
        let s = file.settings();
        let mut want = Settings::default();
        want.core.max_pushes = 1;
        want.segmenter.seed = 7;
        want.flow.coarsest_level = Some(4);
        assert_eq!(s, want);
        assert_eq!(
            file.flow_over(FlowParams::FINE).unwrap(),
            FlowParams {
                coarsest_level: Some(4),
                ..FlowParams::FINE
            }
        );
        // An integer for a float setting is read as the float.
        let f = ConfigFile::parse("int.toml", "[core]\ngrow_tol_px = 3\n").unwrap();
        assert!((f.settings().core.grow_tol_px - 3.0).abs() < f32::EPSILON);
    }

    #[test]
    fn errors_name_the_file_the_section_and_the_key() {
        let err = |text: &str| {
            ConfigFile::parse("my.toml", text)
                .map(|_| ())
                .unwrap_err()
                .to_string()
        };
        let e = err("[core]\nmax_pushez = 1\n");
        assert!(
            e.starts_with("my.toml: [core] max_pushez: unknown field"),
            "{e}"
        );
        let e = err("[core]\nmax_pushes = \"one\"\n");
        assert!(
            e.starts_with("my.toml: [core] max_pushes: invalid type"),
            "{e}"
        );
        let e = err("[segmenter]\nrim_heat = 300\n");
        assert!(e.starts_with("my.toml: [segmenter] rim_heat:"), "{e}");
        let e = err("[core]\nuncertain_from = 200\n");
        assert!(
            e.starts_with("my.toml: [core] uncertain_from = 200: out of range"),
            "{e}"
        );
        let e = err("[segmenter]\nplane_inlier_m = -1.0\n");
        assert!(
            e.starts_with("my.toml: [segmenter]") && e.contains("plane_inlier_m"),
            "{e}"
        );
        let e = err("[flow]\npatch_size_px = 5\n");
        assert!(
            e.starts_with("my.toml: [flow]") && e.contains("patch_size_px"),
            "{e}"
        );
        let e = err("[cor]\nmax_pushes = 1\n");
        assert!(
            e.starts_with("my.toml: unknown section or key `cor`"),
            "{e}"
        );
        let e = err("max_pushes = 1\n");
        assert!(
            e.starts_with("my.toml: unknown section or key `max_pushes`"),
            "{e}"
        );
        let e = err("[core\n");
        assert!(e.starts_with("my.toml: "), "{e}");
    }

    #[test]
    fn doc_links_become_plain_code() {
        assert_eq!(
            plain("see [`Twist::distance`] and [`A`](super::A), [x]"),
            "see `Twist::distance` and `A`, [x]"
        );
    }
}
