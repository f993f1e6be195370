//! Reading declarations out of the WGSL sources as text, for the tests that check the kernels
//! against the Rust side (constants, and the uniforms declared with [`crate::wgsl_mirror!`]
//! through [`check_mirror`]): no GPU and no `wgpu` feature needed.
//!
//! What it is not: a WGSL parser. It reads `const NAME: T = EXPR;` lines (EXPR a literal or
//! `a / b`) and `struct Name { field: type, ... }` declarations of scalars, vectors and
//! fixed-size arrays, and panics on anything else, naming it.

/// The value of `const NAME: TYPE = EXPR;` in `src`, where EXPR is a literal or `a / b` (WGSL
/// evaluates constant expressions exactly, then converts to the type).
pub fn const_value(src: &str, name: &str) -> f64 {
    let prefix = format!("const {name}:");
    let line = src
        .lines()
        .find(|l| l.trim_start().starts_with(&prefix))
        .unwrap_or_else(|| panic!("the WGSL source declares no `{name}`"));
    let expr = line
        .split_once('=')
        .and_then(|(_, e)| e.trim().strip_suffix(';'))
        .unwrap_or_else(|| panic!("`{line}` is not `const {name}: T = EXPR;`"));
    let literal = |s: &str| -> f64 {
        let s = s.trim();
        s.strip_suffix('u')
            .unwrap_or(s)
            .parse()
            .unwrap_or_else(|e| panic!("{name}: `{s}`: {e}"))
    };
    match expr.split_once('/') {
        Some((a, b)) => literal(a) / literal(b),
        None => literal(expr),
    }
}

/// One member of a WGSL struct as laid out in memory (WGSL's alignment rules).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Member {
    /// The member's name.
    pub name: String,
    /// The type as written, e.g. `f32`, `vec3<f32>`.
    pub ty: String,
    /// Byte offset in the struct.
    pub offset: usize,
    /// Size in bytes.
    pub size: usize,
}

/// Size and alignment of a WGSL type (scalars, vectors, fixed-size arrays of those).
fn size_align(ty: &str) -> (usize, usize) {
    let ty = ty.trim();
    match ty {
        "f32" | "u32" | "i32" => return (4, 4),
        _ => {}
    }
    for (prefix, n) in [("vec2<", 2), ("vec3<", 3), ("vec4<", 4)] {
        if let Some(inner) = ty.strip_prefix(prefix).and_then(|r| r.strip_suffix('>')) {
            let (s, _) = size_align(inner);
            let align = if n == 3 { 4 * s } else { n * s };
            return (n * s, align);
        }
    }
    if let Some(inner) = ty.strip_prefix("array<").and_then(|r| r.strip_suffix('>')) {
        let (elem, count) = inner
            .rsplit_once(',')
            .unwrap_or_else(|| panic!("`{ty}`: only fixed-size arrays are supported"));
        let (s, a) = size_align(elem);
        let count: usize = count
            .trim()
            .trim_end_matches('u')
            .parse()
            .unwrap_or_else(|e| panic!("`{ty}`: element count: {e}"));
        return (count * s.next_multiple_of(a), a);
    }
    panic!("WGSL type `{ty}` is not supported by this reader")
}

/// The members of `struct NAME { ... }` in `src`, in declaration order with their offsets,
/// and the struct's size.
pub fn struct_layout(src: &str, name: &str) -> (Vec<Member>, usize) {
    let head = format!("struct {name} {{");
    let start = src
        .find(&head)
        .unwrap_or_else(|| panic!("the WGSL source declares no `struct {name}`"));
    let body = &src[start + head.len()..];
    let body = &body[..body
        .find('}')
        .unwrap_or_else(|| panic!("`struct {name}` is not closed"))];
    // Strip line comments, then split members on commas (a type's own commas sit inside <>).
    let text: String = body
        .lines()
        .map(|l| l.split_once("//").map_or(l, |(code, _)| code))
        .collect::<Vec<_>>()
        .join("\n");
    let mut decls = Vec::new();
    let (mut depth, mut current) = (0i32, String::new());
    for ch in text.chars() {
        match ch {
            '<' => depth += 1,
            '>' => depth -= 1,
            _ => {}
        }
        if ch == ',' && depth == 0 {
            decls.push(std::mem::take(&mut current));
        } else {
            current.push(ch);
        }
    }
    decls.push(current);
    let (mut members, mut end, mut max_align) = (Vec::new(), 0usize, 1usize);
    for decl in decls.iter().map(|d| d.trim()).filter(|d| !d.is_empty()) {
        let (field, ty) = decl
            .split_once(':')
            .unwrap_or_else(|| panic!("`struct {name}`: `{decl}` is not `name: type`"));
        let (size, align) = size_align(ty);
        let offset = end.next_multiple_of(align);
        members.push(Member {
            name: field.trim().to_string(),
            ty: ty.trim().to_string(),
            offset,
            size,
        });
        end = offset + size;
        max_align = max_align.max(align);
    }
    (members, end.next_multiple_of(max_align))
}

/// `(name, type, byte offset, byte size)` of each field, as [`crate::wgsl_mirror!`] records them.
pub type Fields = &'static [(&'static str, &'static str, usize, usize)];

/// Panics, naming the struct and the first difference, unless the Rust fields (`fields`, from
/// a [`crate::wgsl_mirror!`] struct's `FIELDS`) and size equal the WGSL declaration of
/// `wgsl_name` in `src`.
pub fn check_mirror(fields: Fields, rust_size: usize, src: &str, wgsl_name: &str) {
    let (members, wgsl_size) = struct_layout(src, wgsl_name);
    let wgsl: Vec<(&str, &str, usize, usize)> = members
        .iter()
        .map(|m| (m.name.as_str(), m.ty.as_str(), m.offset, m.size))
        .collect();
    for (k, (r, w)) in fields.iter().zip(&wgsl).enumerate() {
        assert_eq!(
            r, w,
            "{wgsl_name} field {k}: Rust (name, type, offset, size) vs WGSL"
        );
    }
    assert_eq!(fields.len(), wgsl.len(), "{wgsl_name}: number of fields");
    assert_eq!(rust_size, wgsl_size, "{wgsl_name}: size in bytes");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_follow_wgsl_alignment() {
        let src = "struct S {\n    a: f32, // note, with a comma\n    b: vec3<f32>,\n    c: u32,\n    \
                   d: array<vec2<f32>, 3>,\n    e: vec2<u32>\n}";
        let (members, size) = struct_layout(src, "S");
        let got: Vec<(&str, usize, usize)> = members
            .iter()
            .map(|m| (m.name.as_str(), m.offset, m.size))
            .collect();
        assert_eq!(
            got,
            [
                ("a", 0, 4),
                ("b", 16, 12),
                ("c", 28, 4),
                ("d", 32, 24),
                ("e", 56, 8)
            ]
        );
        assert_eq!(size, 64);
        assert_eq!(members[3].ty, "array<vec2<f32>, 3>");
    }

    #[test]
    fn constants_are_evaluated() {
        let src = "const A: f32 = 1.0 / 255.0;\nconst B: u32 = 16u;";
        assert_eq!(const_value(src, "A") as f32, 1.0 / 255.0);
        assert_eq!(const_value(src, "B"), 16.0);
    }

    #[test]
    fn missing_declarations_are_refused() {
        assert!(std::panic::catch_unwind(|| const_value("", "NO_SUCH")).is_err());
        assert!(std::panic::catch_unwind(|| struct_layout("", "NoSuch")).is_err());
        assert!(
            std::panic::catch_unwind(|| struct_layout("struct T { m: mat2x2<f32> }", "T")).is_err()
        );
    }
}
