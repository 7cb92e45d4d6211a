//! The cause of a hold, from the hand command node's reason ([`HoldCause`]): the summary
//! counts holds by cause, its numbers as `N` (the JSON's `hold_causes`), and the text says the
//! cause with the numbers its reasons had (from the smallest to the largest of each).

/// A piece of a hold's cause: text, or a number (the smallest and the largest seen, each with
/// its text as the reason wrote it).
#[derive(Debug, Clone, PartialEq)]
enum Piece {
    Text(String),
    Number {
        low: (f64, String),
        high: (f64, String),
    },
}

/// The cause of a hold (the text of its reason before its details, the parts up to the first
/// with a number) with its numbers; the numbers of the holds of the same cause widen it
/// ([`HoldCause::widen`]).
#[derive(Debug, Clone, PartialEq)]
pub struct HoldCause(Vec<Piece>);

impl HoldCause {
    /// The cause of a hold for `reason`: the text before its details, the parts up to the
    /// first with a number (`grasp state: stale` of `grasp state: stale: 12.1 ms old, limit
    /// 10.0 ms`), with the numbers of the first part.
    pub fn of(reason: &str) -> Self {
        let mut parts = reason.split(':');
        let mut head = parts.next().unwrap_or(reason).trim().to_string();
        if !head.chars().any(|c| c.is_ascii_digit()) {
            for part in parts.take_while(|p| !p.chars().any(|c| c.is_ascii_digit())) {
                head.push(':');
                head.push_str(part);
            }
        }
        let head = head.trim();
        let mut pieces = Vec::new();
        let (mut text, mut number) = (String::new(), String::new());
        let mut in_number = false;
        for ch in head.chars() {
            if ch.is_ascii_digit() || (in_number && ch == '.') {
                if !in_number {
                    pieces.push(Piece::Text(std::mem::take(&mut text)));
                }
                in_number = true;
                number.push(ch);
            } else {
                if in_number {
                    pieces.push(Self::number(std::mem::take(&mut number)));
                }
                in_number = false;
                text.push(ch);
            }
        }
        if in_number {
            pieces.push(Self::number(number));
        } else {
            pieces.push(Piece::Text(text));
        }
        pieces.retain(|p| *p != Piece::Text(String::new()));
        Self(pieces)
    }

    fn number(text: String) -> Piece {
        let value = text.trim_end_matches('.').parse().unwrap_or(f64::NAN);
        Piece::Number {
            low: (value, text.clone()),
            high: (value, text),
        }
    }

    /// The cause as the summary's JSON counts it: its numbers as `N`.
    pub fn key(&self) -> String {
        self.0
            .iter()
            .map(|p| match p {
                Piece::Text(t) => t.as_str(),
                Piece::Number { .. } => "N",
            })
            .collect()
    }

    /// Takes the numbers of `other`, a hold of the same cause ([`HoldCause::key`]): each of
    /// this one's is then the smallest to the largest of both.
    pub fn widen(&mut self, other: &Self) {
        for (mine, theirs) in self.0.iter_mut().zip(&other.0) {
            if let (Piece::Number { low, high }, Piece::Number { low: l, high: h }) = (mine, theirs)
            {
                if l.0 < low.0 {
                    *low = l.clone();
                }
                if h.0 > high.0 {
                    *high = h.clone();
                }
            }
        }
    }

    /// The cause with its numbers, each as one number or as a range (`no wrench space for 31.5
    /// to 40.2 ms`).
    pub fn shown(&self) -> String {
        self.0
            .iter()
            .map(|p| match p {
                Piece::Text(t) => t.clone(),
                Piece::Number { low, high } if low.1 == high.1 => low.1.clone(),
                Piece::Number { low, high } => format!("{} to {}", low.1, high.1),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cause of a hold, from its reason, as the summary's JSON counts it: the text before its
    /// details, the parts up to the first with a number (`grasp state: stale` of `grasp state:
    /// stale: 12.1 ms old, limit 10.0 ms`), numbers in the first part as `N`.
    fn cause(reason: &str) -> String {
        HoldCause::of(reason).key()
    }

    #[test]
    fn a_holds_cause_is_its_reason_without_the_details() {
        assert_eq!(
            cause("grasp state is stale: 12.1 ms old, limit 10.0 ms"),
            "grasp state is stale"
        );
        assert_eq!(
            cause("grasp state: stale: 3.2 ms old, limit 0.0 ms"),
            "grasp state: stale"
        );
        assert_eq!(
            cause("the estimate is off: pose innovation 3.20 deg over the bound 2.00 deg"),
            "the estimate is off"
        );
        assert_eq!(
            cause("no wrench space for 31.5 ms"),
            "no wrench space for N ms"
        );
        assert_eq!(
            cause("quality alpha* = 0.0812 below the margin alpha = 0.1"),
            "quality alpha* = N below the margin alpha = N"
        );
        assert_eq!(cause("12 ms"), "N ms");
        assert_eq!(cause("held 12"), "held N");
        assert_eq!(cause(""), "");
    }

    #[test]
    fn the_text_says_the_causes_real_numbers_from_the_smallest_to_the_largest() {
        let mut c = HoldCause::of("no wrench space for 31.5 ms");
        assert_eq!(c.shown(), "no wrench space for 31.5 ms");
        c.widen(&HoldCause::of("no wrench space for 31.5 ms"));
        assert_eq!(c.shown(), "no wrench space for 31.5 ms");
        c.widen(&HoldCause::of("no wrench space for 120.0 ms"));
        c.widen(&HoldCause::of("no wrench space for 30.9 ms"));
        assert_eq!(c.shown(), "no wrench space for 30.9 to 120.0 ms");
        assert_eq!(c.key(), "no wrench space for N ms");
        let mut q = HoldCause::of("quality alpha* = 0.0812 below the margin alpha = 0.1");
        q.widen(&HoldCause::of(
            "quality alpha* = 0.0650 below the margin alpha = 0.1",
        ));
        assert_eq!(
            q.shown(),
            "quality alpha* = 0.0650 to 0.0812 below the margin alpha = 0.1"
        );
        // Without numbers: the cause as the JSON has it.
        let s = HoldCause::of("grasp state is stale: 12.1 ms old, limit 10.0 ms");
        assert_eq!(s.shown(), s.key());
    }
}
