//! The shape check: a parsed JSON document walked against the scene's own JSON Schema
//! (generated from the serde types), collecting every problem with its JSON path instead
//! of stopping at the first one as serde does.
//!
//! It understands the subset of JSON Schema that `schemars` emits for the scene types:
//! `$ref`, `type`, `const`, `enum`, `oneOf`/`anyOf`, `properties`, `required`,
//! `additionalProperties: false`, `items`, `minItems`/`maxItems`, `minimum`/`maximum` and
//! the unsigned integer `format`s.

use serde_json::{Map, Value};

use super::Problem;

/// Every shape problem of `doc` against `schema` (the root schema with its `$defs`), and
/// the paths of the unknown keys among them.
pub(crate) fn check_detailed(doc: &Value, schema: &Value) -> (Vec<Problem>, Vec<String>) {
    let mut walker = Walker::new(schema);
    if doc.is_object() {
        walker.walk(doc, schema, "", Some("the scene"));
    } else {
        walker.push("", format!("a scene is a JSON object such as {{\"inkwarp\": 1, \"layers\": [...]}}, found {}", describe(doc)));
    }
    (walker.problems, walker.unknown_keys)
}

struct Walker<'a> {
    root: &'a Value,
    problems: Vec<Problem>,
    unknown_keys: Vec<String>,
}

/// `schema` with a `$ref` into `root`'s `$defs` followed, and the definition's name.
pub(crate) fn resolve_ref<'a>(schema: &'a Value, root: &'a Value) -> (&'a Value, Option<&'a str>) {
    let name = schema.get("$ref").and_then(Value::as_str).and_then(|r| r.strip_prefix("#/$defs/"));
    name.and_then(|name| Some((root.get("$defs")?.get(name)?, Some(name)))).unwrap_or((schema, None))
}

impl<'a> Walker<'a> {
    fn new(root: &'a Value) -> Self { Walker { root, problems: Vec::new(), unknown_keys: Vec::new() } }

    fn resolve(&self, schema: &'a Value) -> (&'a Value, Option<&'a str>) { resolve_ref(schema, self.root) }

    /// Checks `value` at `path`; returns whether it passed.
    fn walk(&mut self, value: &Value, schema: &'a Value, path: &str, what: Option<&str>) -> bool {
        let before = self.problems.len();
        let (schema, def_name) = self.resolve(schema);
        let what = def_name.map(object_noun).or(what);

        if let Some(alternatives) = schema.get("oneOf").or_else(|| schema.get("anyOf")).and_then(Value::as_array) {
            return self.alternatives(value, alternatives, path, what);
        }
        if let Some(types) = schema.get("type").filter(|types| !type_matches(value, types)) {
            let expected = expected_types(types);
            // A whole number past 64 bits reads as a float: it is too large, however it was written.
            let hint = match value.as_f64().filter(|f| expected == "a whole number" && f.fract() == 0.0) {
                Some(f) if f.abs() >= 2f64.powi(63) => ", too large to be one here; use a smaller number",
                Some(_) => "; write it without a decimal point or exponent (2, not 2.0)",
                None if expected.starts_with("a list") && value.as_str().is_some_and(|s| s.starts_with('#')) => "; write a colour as a list [r, g, b, a] of 0–255 (\"#ff8000\" is [255, 128, 0, 255])",
                None => "",
            };
            self.push(path, format!("expected {expected}, found {}{hint}", describe(value)));
            return false;
        }
        if let Some(constant) = schema.get("const").filter(|&c| c != value) {
            let found = describe(value);
            let why = if path == "inkwarp" {
                format!("this inkwarp reads scene format {constant}, found {found}; set \"inkwarp\": {constant} (and convert the scene if it was written for another format)")
            } else {
                format!("must be {constant}, found {found}")
            };
            self.push(path, why);
            return false;
        }
        if let Some(options) = schema.get("enum").and_then(Value::as_array).filter(|options| !options.contains(value)) {
            self.push(path, format!("{} is not allowed here; use one of {}", describe(value), list(options)));
            return false;
        }
        match value {
            Value::Object(map) => self.object(map, schema, path, what),
            Value::Array(items) => self.array(items, schema, path),
            Value::Number(_) => self.number(value, schema, path),
            _ => {}
        }
        self.problems.len() == before
    }

    fn alternatives(&mut self, value: &Value, alternatives: &'a [Value], path: &str, what: Option<&str>) -> bool {
        // All-constant alternatives are an enumeration of names (kinds, methods, ...).
        let constants: Vec<&Value> = alternatives.iter().filter_map(|a| self.resolve(a).0.get("const")).collect();
        if constants.len() == alternatives.len() {
            if constants.contains(&value) {
                return true;
            }
            let noun = path.rsplit('.').next().unwrap_or("value");
            let noun = noun.split('[').next().unwrap_or(noun);
            let names: Vec<Value> = constants.into_iter().cloned().collect();
            let hint = value
                .as_str()
                .and_then(|s| did_you_mean(s, names.iter().filter_map(Value::as_str)))
                .map(|s| format!(" (did you mean \"{s}\"?)"))
                .unwrap_or_default();
            let found = match value {
                Value::String(s) => format!("unknown {noun} \"{s}\""),
                other => format!("expected a {noun} name, found {}", describe(other)),
            };
            self.push(path, format!("{found}; use one of {}{hint}", list(&names)));
            return false;
        }
        // Otherwise: the first alternative that passes; failing that, the problems of the
        // alternative whose type fits the value (for `Option<T>`: T's problems).
        if alternatives.iter().any(|a| Walker::new(self.root).walk(value, a, path, what)) {
            return true;
        }
        let fitting = alternatives.iter().find(|a| {
            let (resolved, _) = self.resolve(a);
            match resolved.get("type") {
                Some(types) => type_matches(value, types) && !value.is_null(),
                None => resolved.get("oneOf").is_some() || resolved.get("anyOf").is_some(),
            }
        });
        if let Some(alternative) = fitting {
            self.walk(value, alternative, path, what);
            return false;
        }
        let expected: Vec<String> = alternatives
            .iter()
            .map(|a| match self.resolve(a) {
                (_, Some(name)) => object_noun(name).to_string(),
                (resolved, None) => resolved.get("type").map_or("a value".to_string(), expected_types),
            })
            .collect();
        self.push(path, format!("expected {}, found {}", expected.join(" or "), describe(value)));
        false
    }

    fn object(&mut self, map: &Map<String, Value>, schema: &'a Value, path: &str, what: Option<&str>) {
        let properties = schema.get("properties").and_then(Value::as_object);
        let what = what.unwrap_or("this object");
        if let Some(properties) = properties {
            let closed = schema.get("additionalProperties") == Some(&Value::Bool(false));
            for (key, value) in map {
                match properties.get(key) {
                    Some(property) => _ = self.walk(value, property, &join_key(path, key), None),
                    None if closed => {
                        let names = properties.keys().map(String::as_str);
                        let hint = did_you_mean(key, names.clone()).map(|s| format!("did you mean \"{s}\"? ")).unwrap_or_default();
                        let valid: Vec<&str> = names.collect();
                        self.unknown_keys.push(join_key(path, key));
                        let why = format!("unknown key \"{key}\" in {what}; {hint}the keys of {what} are {}", valid.join(", "));
                        self.push(&join_key(path, key), why);
                    }
                    None => {}
                }
            }
        }
        if let Some(required) = schema.get("required").and_then(Value::as_array) {
            for key in required.iter().filter_map(Value::as_str).filter(|key| !map.contains_key(*key)) {
                let about = properties
                    .and_then(|p| p.get(key))
                    .and_then(|p| p.get("description"))
                    .and_then(Value::as_str)
                    .map(|d| format!(" ({})", first_sentence(d)))
                    .unwrap_or_default();
                self.push(&join_key(path, key), format!("{what} needs \"{key}\"{about}; add it"));
            }
        }
    }

    fn array(&mut self, items: &[Value], schema: &'a Value, path: &str) {
        let min = schema.get("minItems").and_then(Value::as_u64);
        let max = schema.get("maxItems").and_then(Value::as_u64);
        let n = items.len() as u64;
        let count_ok = !matches!(min, Some(m) if n < m) && !matches!(max, Some(m) if n > m);
        if !count_ok {
            let wanted = match (min, max) {
                (Some(a), Some(b)) if a == b && a == 2 => "exactly 2 numbers [x, y]".to_string(),
                (Some(a), Some(b)) if a == b => format!("exactly {a} items{}", if path == "background" { " [R, G, B, A], each 0 to 255" } else { "" }),
                (Some(a), Some(b)) => format!("{a} to {b} items"),
                (Some(a), None) => format!("at least {a} items"),
                (None, Some(b)) => format!("at most {b} items"),
                (None, None) => unreachable!(),
            };
            self.push(path, format!("expected {wanted}, found {n}"));
            return;
        }
        if let Some(item_schema) = schema.get("items") {
            for (i, item) in items.iter().enumerate() {
                self.walk(item, item_schema, &format!("{path}[{i}]"), None);
            }
        }
    }

    fn number(&mut self, value: &Value, schema: &Value, path: &str) {
        let x = value.as_f64().unwrap_or(f64::NAN);
        let limit = match schema.get("format").and_then(Value::as_str) {
            Some("uint8") => u8::MAX as f64,
            Some("uint16") => u16::MAX as f64,
            Some("uint32") => u32::MAX as f64,
            _ => f64::INFINITY,
        };
        if x > limit {
            self.push(path, format!("must be at most {limit}, found {value}"));
            return;
        }
        if let Some(min) = schema.get("minimum").and_then(Value::as_f64).filter(|&min| x < min) {
            self.push(path, format!("must be at least {}, found {value}", fmt_num(min)));
            return;
        }
        if let Some(max) = schema.get("maximum").and_then(Value::as_f64).filter(|&max| x > max) {
            self.push(path, format!("must be at most {}, found {value}", fmt_num(max)));
        }
    }

    fn push(&mut self, path: &str, message: String) {
        self.problems.push(Problem::new(path, message));
    }
}

/// The noun for an object of a schema definition, for messages.
fn object_noun(def_name: &str) -> &'static str {
    match def_name {
        "SceneDoc" => "the scene",
        "SolverDoc" => "the solver settings",
        "SolverOverrides" => "a layer's solver overrides",
        "LayerDoc" => "a layer",
        "FeatureDoc" => "a feature",
        "KeyDoc" => "a key",
        "BeierNeelyDoc" => "Beier–Neely's weights",
        "TpsExactDoc" => "tps-exact's settings",
        _ => "this object",
    }
}

pub(crate) fn join_key(path: &str, key: &str) -> String {
    if path.is_empty() { key.to_string() } else { format!("{path}.{key}") }
}

/// JSON Schema's types: how to tell a value of each, and how messages name it.
#[allow(clippy::type_complexity)]
const TYPES: [(&str, fn(&Value) -> bool, &str); 7] = [
    ("object", Value::is_object, "an object {...}"),
    ("array", Value::is_array, "a list [...]"),
    ("string", Value::is_string, "a string"),
    ("boolean", Value::is_boolean, "true or false"),
    ("null", Value::is_null, "null"),
    ("number", Value::is_number, "a number"),
    ("integer", |v| v.is_u64() || v.is_i64(), "a whole number"),
];

fn type_matches(value: &Value, types: &Value) -> bool {
    let one = |t: &str| TYPES.iter().find(|e| e.0 == t).map_or(true, |e| (e.1)(value));
    match types {
        Value::String(t) => one(t),
        Value::Array(ts) => ts.iter().filter_map(Value::as_str).any(one),
        _ => true,
    }
}

fn expected_types(types: &Value) -> String {
    let name = |t: &str| TYPES.iter().find(|e| e.0 == t).map_or("a value", |e| e.2);
    match types {
        Value::String(t) => name(t).to_string(),
        // `Option<T>` is "T or null": null means "absent", so name only T.
        Value::Array(ts) => ts.iter().filter_map(Value::as_str).filter(|t| *t != "null").map(name).collect::<Vec<_>>().join(" or "),
        _ => "a value".to_string(),
    }
}

/// A short description of a JSON value for messages: its type and a glimpse of it.
pub(crate) fn describe(value: &Value) -> String {
    match value {
        Value::Null => "null".to_string(),
        Value::Bool(b) => b.to_string(),
        Value::Number(n) => format!("the number {n}"),
        Value::String(s) if s.chars().count() > 40 => {
            format!("the string \"{}...\"", s.chars().take(37).collect::<String>())
        }
        Value::String(s) => format!("the string \"{s}\""),
        Value::Array(a) => format!("a list of {} item{}", a.len(), if a.len() == 1 { "" } else { "s" }),
        Value::Object(_) => "an object".to_string(),
    }
}

fn list(values: &[Value]) -> String {
    let name = |v: &Value| if let Value::String(s) = v { format!("\"{s}\"") } else { v.to_string() };
    values.iter().map(name).collect::<Vec<_>>().join(", ")
}

fn fmt_num(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e15 { format!("{}", x as i64) } else { format!("{x}") }
}

fn first_sentence(text: &str) -> String {
    let text = text.replace('\n', " ");
    text.find(". ").map_or_else(|| text.trim_end_matches('.').to_string(), |i| text[..i].to_string())
}

/// The candidate closest to `word` by edit distance, when it is close enough to be a typo.
pub(crate) fn did_you_mean<'b>(word: &str, candidates: impl Iterator<Item = &'b str> + Clone) -> Option<&'b str> {
    // A drawing program's word for a kind, and the usual word for a key's `t`, first ("dot" is nearer "cut" by its letters).
    const SYNONYMS: [(&str, &str); 11] = [("dot", "point"), ("pin", "point"), ("line", "polyline"), ("path", "polyline"),
        ("curve", "spline"), ("bezier", "spline"), ("shape", "region"), ("area", "region"), ("polygon", "region"), ("tear", "cut"), ("time", "t")];
    let word_l = word.to_lowercase();
    if let Some(&(_, to)) = SYNONYMS.iter().find(|(from, _)| *from == word_l) {
        if let Some(c) = candidates.clone().find(|c| *c == to) { return Some(c) }
    }
    // Nearest first by the words without their separators ("easeinout" is "ease-in-out").
    let bare = |s: &str| s.to_lowercase().replace(['-', '_', ' '], "");
    candidates
        .map(|c| (edit_distance(&word_l, &c.to_lowercase()), edit_distance(&bare(word), &bare(c)), c))
        .filter(|(d, _, c)| *d <= 2.max(c.len() / 3) && *d < c.len().max(word.len()))
        .min_by_key(|(d, bare, _)| (*bare, *d))
        .map(|(.., c)| c)
}

fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for i in 1..=a.len() {
        let mut diagonal = row[0];
        row[0] = i;
        for j in 1..=b.len() {
            let above = row[j];
            row[j] = (row[j] + 1).min(row[j - 1] + 1).min(diagonal + usize::from(a[i - 1] != b[j - 1]));
            diagonal = above;
        }
    }
    row[b.len()]
}
