//! A small bitmap font of our own for the legends: printable ASCII (32..=126), each glyph 5
//! pixels wide on a 9-row cell (7 rows from the cap line to the baseline, 2 below it for the
//! descenders of g, j, p, q, y and commas). Glyphs are written as pictures (`#` on, `.` off,
//! rows separated by spaces, missing bottom rows empty) and turned into bit rows at compile
//! time, so a malformed glyph fails the build rather than a render.

/// Pixels of a glyph across.
pub(super) const GLYPH_W: u32 = 5;
/// Rows of a glyph cell: 7 above the baseline, 2 below.
pub(super) const GLYPH_H: u32 = 9;
/// Rows from the top of the cell to the baseline (the cap height).
pub(super) const CAP_H: u32 = 7;
/// Horizontal advance from one glyph to the next, in font pixels (one pixel of spacing).
pub(super) const ADVANCE: u32 = GLYPH_W + 1;

const FIRST: u8 = b' ';
const LAST: u8 = b'~';
const COUNT: usize = (LAST - FIRST) as usize + 1;

/// The glyphs in ASCII order; the character beside each picture is checked at compile time.
const PICTURES: [(u8, &str); COUNT] = [
    (b' ', ""),
    (b'!', "..#.. ..#.. ..#.. ..#.. ..#.. ..... ..#.."),
    (b'"', ".#.#. .#.#. .#.#."),
    (b'#', ".#.#. .#.#. ##### .#.#. ##### .#.#. .#.#."),
    (b'$', "..#.. .#### #.#.. .###. ..#.# ####. ..#.."),
    (b'%', "##... ##..# ...#. ..#.. .#... #..## ...##"),
    (b'&', ".##.. #..#. #.#.. .#... #.#.# #..#. .##.#"),
    (b'\'', "..#.. ..#.. .#..."),
    (b'(', "...#. ..#.. .#... .#... .#... ..#.. ...#."),
    (b')', ".#... ..#.. ...#. ...#. ...#. ..#.. .#..."),
    (b'*', "..... ..#.. #.#.# .###. #.#.# ..#.."),
    (b'+', "..... ..#.. ..#.. ##### ..#.. ..#.."),
    (b',', "..... ..... ..... ..... ..... .##.. ..#.. .#..."),
    (b'-', "..... ..... ..... #####"),
    (b'.', "..... ..... ..... ..... ..... .##.. .##.."),
    (b'/', "....# ....# ...#. ..#.. .#... #.... #...."),
    (b'0', ".###. #...# #..## #.#.# ##..# #...# .###."),
    (b'1', "..#.. .##.. ..#.. ..#.. ..#.. ..#.. .###."),
    (b'2', ".###. #...# ....# ...#. ..#.. .#... #####"),
    (b'3', "##### ...#. ..#.. ...#. ....# #...# .###."),
    (b'4', "...#. ..##. .#.#. #..#. ##### ...#. ...#."),
    (b'5', "##### #.... ####. ....# ....# #...# .###."),
    (b'6', "..##. .#... #.... ####. #...# #...# .###."),
    (b'7', "##### ....# ...#. ..#.. .#... .#... .#..."),
    (b'8', ".###. #...# #...# .###. #...# #...# .###."),
    (b'9', ".###. #...# #...# .#### ....# ...#. .##.."),
    (b':', "..... .##.. .##.. ..... .##.. .##.."),
    (b';', "..... .##.. .##.. ..... .##.. ..#.. .#..."),
    (b'<', "...#. ..#.. .#... #.... .#... ..#.. ...#."),
    (b'=', "..... ..... ##### ..... #####"),
    (b'>', ".#... ..#.. ...#. ....# ...#. ..#.. .#..."),
    (b'?', ".###. #...# ....# ...#. ..#.. ..... ..#.."),
    (b'@', ".###. #...# #.### #.#.# #.##. #.... .####"),
    (b'A', ".###. #...# #...# ##### #...# #...# #...#"),
    (b'B', "####. #...# #...# ####. #...# #...# ####."),
    (b'C', ".###. #...# #.... #.... #.... #...# .###."),
    (b'D', "###.. #..#. #...# #...# #...# #..#. ###.."),
    (b'E', "##### #.... #.... ####. #.... #.... #####"),
    (b'F', "##### #.... #.... ####. #.... #.... #...."),
    (b'G', ".###. #...# #.... #.### #...# #...# .####"),
    (b'H', "#...# #...# #...# ##### #...# #...# #...#"),
    (b'I', ".###. ..#.. ..#.. ..#.. ..#.. ..#.. .###."),
    (b'J', "..### ...#. ...#. ...#. ...#. #..#. .##.."),
    (b'K', "#...# #..#. #.#.. ##... #.#.. #..#. #...#"),
    (b'L', "#.... #.... #.... #.... #.... #.... #####"),
    (b'M', "#...# ##.## #.#.# #.#.# #...# #...# #...#"),
    (b'N', "#...# #...# ##..# #.#.# #..## #...# #...#"),
    (b'O', ".###. #...# #...# #...# #...# #...# .###."),
    (b'P', "####. #...# #...# ####. #.... #.... #...."),
    (b'Q', ".###. #...# #...# #...# #.#.# #..#. .##.#"),
    (b'R', "####. #...# #...# ####. #.#.. #..#. #...#"),
    (b'S', ".#### #.... #.... .###. ....# ....# ####."),
    (b'T', "##### ..#.. ..#.. ..#.. ..#.. ..#.. ..#.."),
    (b'U', "#...# #...# #...# #...# #...# #...# .###."),
    (b'V', "#...# #...# #...# #...# #...# .#.#. ..#.."),
    (b'W', "#...# #...# #...# #.#.# #.#.# #.#.# .#.#."),
    (b'X', "#...# #...# .#.#. ..#.. .#.#. #...# #...#"),
    (b'Y', "#...# #...# .#.#. ..#.. ..#.. ..#.. ..#.."),
    (b'Z', "##### ....# ...#. ..#.. .#... #.... #####"),
    (b'[', ".###. .#... .#... .#... .#... .#... .###."),
    (b'\\', "#.... #.... .#... ..#.. ...#. ....# ....#"),
    (b']', ".###. ...#. ...#. ...#. ...#. ...#. .###."),
    (b'^', "..#.. .#.#. #...#"),
    (b'_', "..... ..... ..... ..... ..... ..... ..... #####"),
    (b'`', ".#... ..#.."),
    (b'a', "..... ..... .###. ....# .#### #...# .####"),
    (b'b', "#.... #.... #.##. ##..# #...# #...# ####."),
    (b'c', "..... ..... .###. #.... #.... #...# .###."),
    (b'd', "....# ....# .##.# #..## #...# #...# .####"),
    (b'e', "..... ..... .###. #...# ##### #.... .###."),
    (b'f', "..##. .#..# .#... ###.. .#... .#... .#..."),
    (
        b'g',
        "..... ..... .#### #...# #...# #...# .#### ....# .###.",
    ),
    (b'h', "#.... #.... #.##. ##..# #...# #...# #...#"),
    (b'i', "..#.. ..... .##.. ..#.. ..#.. ..#.. .###."),
    (
        b'j',
        "...#. ..... ..##. ...#. ...#. ...#. ...#. #..#. .##..",
    ),
    (b'k', "#.... #.... #..#. #.#.. ##... #.#.. #..#."),
    (b'l', ".##.. ..#.. ..#.. ..#.. ..#.. ..#.. .###."),
    (b'm', "..... ..... ##.#. #.#.# #.#.# #.#.# #.#.#"),
    (b'n', "..... ..... #.##. ##..# #...# #...# #...#"),
    (b'o', "..... ..... .###. #...# #...# #...# .###."),
    (
        b'p',
        "..... ..... ####. #...# #...# #...# ####. #.... #....",
    ),
    (
        b'q',
        "..... ..... .#### #...# #...# #...# .#### ....# ....#",
    ),
    (b'r', "..... ..... #.##. ##..# #.... #.... #...."),
    (b's', "..... ..... .#### #.... .###. ....# ####."),
    (b't', ".#... .#... ###.. .#... .#... .#..# ..##."),
    (b'u', "..... ..... #...# #...# #...# #..## .##.#"),
    (b'v', "..... ..... #...# #...# #...# .#.#. ..#.."),
    (b'w', "..... ..... #...# #...# #.#.# #.#.# .#.#."),
    (b'x', "..... ..... #...# .#.#. ..#.. .#.#. #...#"),
    (
        b'y',
        "..... ..... #...# #...# #...# #...# .#### ....# .###.",
    ),
    (b'z', "..... ..... ##### ...#. ..#.. .#... #####"),
    (b'{', "...#. ..#.. ..#.. .#... ..#.. ..#.. ...#."),
    (b'|', "..#.. ..#.. ..#.. ..#.. ..#.. ..#.. ..#.. ..#.."),
    (b'}', ".#... ..#.. ..#.. ...#. ..#.. ..#.. .#..."),
    (b'~', "..... ..... .#... #.#.# ...#."),
];

/// One glyph: a row of bits per cell row, bit 4 the leftmost pixel.
pub(super) type Glyph = [u8; GLYPH_H as usize];

/// The glyphs in ASCII order from `' '`.
const GLYPHS: [Glyph; COUNT] = parse_all();

const fn parse_all() -> [Glyph; COUNT] {
    let mut out = [[0u8; GLYPH_H as usize]; COUNT];
    let mut i = 0;
    while i < COUNT {
        let (c, picture) = PICTURES[i];
        assert!(
            c as usize == FIRST as usize + i,
            "glyph pictures out of order"
        );
        out[i] = parse(picture.as_bytes());
        i += 1;
    }
    out
}

/// One picture: rows of exactly five `#` or `.`, separated by single spaces.
const fn parse(p: &[u8]) -> Glyph {
    let mut glyph = [0u8; GLYPH_H as usize];
    let (mut row, mut col, mut i) = (0usize, 0u32, 0usize);
    while i < p.len() {
        match p[i] {
            b' ' => {
                assert!(col == GLYPH_W, "a glyph row is not 5 pixels wide");
                row += 1;
                col = 0;
            }
            b'#' | b'.' => {
                assert!(
                    col < GLYPH_W && row < GLYPH_H as usize,
                    "a glyph is too large"
                );
                if p[i] == b'#' {
                    glyph[row] |= 1 << (GLYPH_W - 1 - col);
                }
                col += 1;
            }
            _ => panic!("a glyph picture holds only '#', '.' and spaces"),
        }
        i += 1;
    }
    assert!(
        col == 0 || col == GLYPH_W,
        "a glyph row is not 5 pixels wide"
    );
    glyph
}

/// The glyph of `c`; a character outside printable ASCII is drawn as `?` so that a name with
/// an accent still shows where it differs.
pub(super) fn glyph(c: char) -> &'static Glyph {
    let code = u32::from(c);
    let index = if (u32::from(FIRST)..=u32::from(LAST)).contains(&code) {
        code - u32::from(FIRST)
    } else {
        u32::from(b'?' - FIRST)
    };
    &GLYPHS[index as usize]
}

/// The width in image pixels of `text` drawn at `scale`: no trailing spacing.
pub(super) fn text_width(text: &str, scale: u32) -> u32 {
    let n = text.chars().count() as u32;
    (n * ADVANCE).saturating_sub(1) * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_printable_glyph_but_space_has_pixels() {
        for code in FIRST..=LAST {
            let lit = glyph(char::from(code))
                .iter()
                .map(|r| r.count_ones())
                .sum::<u32>();
            if code == b' ' {
                assert_eq!(lit, 0, "space is blank");
            } else {
                assert!(lit > 0, "glyph {:?} is empty", char::from(code));
            }
        }
    }

    #[test]
    fn glyphs_are_pairwise_distinct_and_descenders_only_where_expected() {
        for a in FIRST..=LAST {
            for b in a + 1..=LAST {
                assert_ne!(glyph(char::from(a)), glyph(char::from(b)), "{a} and {b}");
            }
            let below = glyph(char::from(a))[CAP_H as usize..]
                .iter()
                .any(|&r| r != 0);
            assert_eq!(below, b"gjpqy,_|".contains(&a), "{:?}", char::from(a));
        }
        assert_eq!(glyph('é'), glyph('?'));
        assert_eq!(text_width("ab", 2), 22);
        assert_eq!(text_width("", 2), 0);
    }
}
