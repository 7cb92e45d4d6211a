//! Text cut into lines of a width, at spaces or between the parts of a list: the run's
//! summary and `monitor`'s plain lines.

/// `text` cut into lines of at most `width` characters at spaces (a longer word stays whole).
pub fn wrap(text: &str, width: usize) -> Vec<String> {
    wrap_at(text, " ", width)
}

/// `text` cut into lines of at most `width` characters where `sep` separates its parts (a
/// longer part stays whole); `sep` stays at the end of a line, trimmed.
pub fn wrap_at(text: &str, sep: &str, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for part in text.split(sep) {
        if !line.is_empty()
            && line.chars().count() + sep.chars().count() + part.chars().count() > width
        {
            line.push_str(sep.trim_end());
            lines.push(std::mem::take(&mut line));
        } else if !line.is_empty() {
            line.push_str(sep);
        }
        line.push_str(part);
    }
    if !line.is_empty() || lines.is_empty() {
        lines.push(line);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_wrapped_at_spaces_within_the_width() {
        let text = "bridge 330110 in 11 s, command 11205 in 11 s, estimator 11135 in 11 s, planner 1815 in 11 s";
        let lines = wrap(text, 40);
        assert!(lines.len() > 1);
        assert!(lines.iter().all(|l| l.chars().count() <= 40), "{lines:?}");
        assert_eq!(lines.join(" "), text);
        assert_eq!(wrap("", 10), vec![String::new()]);
        assert_eq!(
            wrap("averyveryverylongword", 5),
            vec!["averyveryverylongword"]
        );
    }
}
