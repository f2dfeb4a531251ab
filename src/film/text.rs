//! A tiny 5×7 bitmap font, to label images (the side-by-side comparison of
//! `trazo compare`) without depending on font files.

use super::Image;
use crate::color::Rgb;

/// Glyph width and height in font pixels.
pub const GLYPH_W: u32 = 5;
/// Glyph height in font pixels.
pub const GLYPH_H: u32 = 7;

/// Rows of a glyph, top first; bit 4 is the leftmost column.
fn glyph(c: char) -> [u8; 7] {
    let rows: [&str; 7] = match c.to_ascii_uppercase() {
        'A' => [" ### ", "#   #", "#   #", "#####", "#   #", "#   #", "#   #"],
        'B' => ["#### ", "#   #", "#   #", "#### ", "#   #", "#   #", "#### "],
        'C' => [" ### ", "#   #", "#    ", "#    ", "#    ", "#   #", " ### "],
        'D' => ["#### ", "#   #", "#   #", "#   #", "#   #", "#   #", "#### "],
        'E' => ["#####", "#    ", "#    ", "#### ", "#    ", "#    ", "#####"],
        'F' => ["#####", "#    ", "#    ", "#### ", "#    ", "#    ", "#    "],
        'G' => [" ### ", "#   #", "#    ", "# ###", "#   #", "#   #", " ####"],
        'H' => ["#   #", "#   #", "#   #", "#####", "#   #", "#   #", "#   #"],
        'I' => [" ### ", "  #  ", "  #  ", "  #  ", "  #  ", "  #  ", " ### "],
        'J' => ["  ###", "   # ", "   # ", "   # ", "   # ", "#  # ", " ##  "],
        'K' => ["#   #", "#  # ", "# #  ", "##   ", "# #  ", "#  # ", "#   #"],
        'L' => ["#    ", "#    ", "#    ", "#    ", "#    ", "#    ", "#####"],
        'M' => ["#   #", "## ##", "# # #", "# # #", "#   #", "#   #", "#   #"],
        'N' => ["#   #", "#   #", "##  #", "# # #", "#  ##", "#   #", "#   #"],
        'O' => [" ### ", "#   #", "#   #", "#   #", "#   #", "#   #", " ### "],
        'P' => ["#### ", "#   #", "#   #", "#### ", "#    ", "#    ", "#    "],
        'Q' => [" ### ", "#   #", "#   #", "#   #", "# # #", "#  # ", " ## #"],
        'R' => ["#### ", "#   #", "#   #", "#### ", "# #  ", "#  # ", "#   #"],
        'S' => [" ####", "#    ", "#    ", " ### ", "    #", "    #", "#### "],
        'T' => ["#####", "  #  ", "  #  ", "  #  ", "  #  ", "  #  ", "  #  "],
        'U' => ["#   #", "#   #", "#   #", "#   #", "#   #", "#   #", " ### "],
        'V' => ["#   #", "#   #", "#   #", "#   #", "#   #", " # # ", "  #  "],
        'W' => ["#   #", "#   #", "#   #", "# # #", "# # #", "# # #", " # # "],
        'X' => ["#   #", "#   #", " # # ", "  #  ", " # # ", "#   #", "#   #"],
        'Y' => ["#   #", "#   #", " # # ", "  #  ", "  #  ", "  #  ", "  #  "],
        'Z' => ["#####", "    #", "   # ", "  #  ", " #   ", "#    ", "#####"],
        '0' => [" ### ", "#   #", "#  ##", "# # #", "##  #", "#   #", " ### "],
        '1' => ["  #  ", " ##  ", "  #  ", "  #  ", "  #  ", "  #  ", " ### "],
        '2' => [" ### ", "#   #", "    #", "   # ", "  #  ", " #   ", "#####"],
        '3' => ["#####", "   # ", "  #  ", "   # ", "    #", "#   #", " ### "],
        '4' => ["   # ", "  ## ", " # # ", "#  # ", "#####", "   # ", "   # "],
        '5' => ["#####", "#    ", "#### ", "    #", "    #", "#   #", " ### "],
        '6' => ["  ## ", " #   ", "#    ", "#### ", "#   #", "#   #", " ### "],
        '7' => ["#####", "    #", "   # ", "  #  ", " #   ", " #   ", " #   "],
        '8' => [" ### ", "#   #", "#   #", " ### ", "#   #", "#   #", " ### "],
        '9' => [" ### ", "#   #", "#   #", " ####", "    #", "   # ", " ##  "],
        '.' => ["     ", "     ", "     ", "     ", "     ", " ##  ", " ##  "],
        ',' => ["     ", "     ", "     ", "     ", " ##  ", "  #  ", " #   "],
        ':' => ["     ", " ##  ", " ##  ", "     ", " ##  ", " ##  ", "     "],
        '-' => ["     ", "     ", "     ", "#####", "     ", "     ", "     "],
        '+' => ["     ", "  #  ", "  #  ", "#####", "  #  ", "  #  ", "     "],
        '=' => ["     ", "     ", "#####", "     ", "#####", "     ", "     "],
        '_' => ["     ", "     ", "     ", "     ", "     ", "     ", "#####"],
        '/' => ["     ", "    #", "   # ", "  #  ", " #   ", "#    ", "     "],
        '(' => ["   # ", "  #  ", " #   ", " #   ", " #   ", "  #  ", "   # "],
        ')' => [" #   ", "  #  ", "   # ", "   # ", "   # ", "  #  ", " #   "],
        '%' => ["##   ", "##  #", "   # ", "  #  ", " #   ", "#  ##", "   ##"],
        '×' => ["     ", "#   #", " # # ", "  #  ", " # # ", "#   #", "     "],
        ' ' => ["     "; 7],
        _ => ["#####", "#   #", "#   #", "#   #", "#   #", "#   #", "#####"],
    };
    rows.map(|r| r.bytes().fold(0u8, |acc, b| (acc << 1) | u8::from(b == b'#')))
}

/// Width in image pixels of `text` drawn at `scale`.
pub fn text_width(text: &str, scale: u32) -> u32 {
    text.chars().count() as u32 * (GLYPH_W + 1) * scale
}

/// The image pixels that `text` drawn at `scale` with its top-left corner
/// at (0, 0) covers.
pub fn text_pixels(text: &str, scale: u32) -> impl Iterator<Item = (u32, u32)> + '_ {
    text.chars().enumerate().flat_map(move |(i, c)| {
        let rows = glyph(c);
        let gx = i as u32 * (GLYPH_W + 1) * scale;
        (0..GLYPH_H * scale).flat_map(move |y| {
            let bits = rows[(y / scale) as usize];
            (0..GLYPH_W * scale)
                .filter(move |x| bits & (1 << (GLYPH_W - 1 - x / scale)) != 0)
                .map(move |x| (gx + x, y))
        })
    })
}

/// Draws `text` with its top-left corner at (x, y), each font pixel a
/// `scale`×`scale` block of `color`. Parts outside the image are clipped.
pub fn draw_text(image: &mut Image, x: u32, y: u32, text: &str, scale: u32, color: Rgb) {
    for (dx, dy) in text_pixels(text, scale) {
        let (px, py) = (x + dx, y + dy);
        if px < image.width && py < image.height {
            image.pixels[(py * image.width + px) as usize] = color;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glyphs_are_drawn_where_asked() {
        let mut img = Image::new(40, 10);
        draw_text(&mut img, 1, 1, "L1", 1, Rgb::ONE);
        // 'L': left column lit on every row, bottom row lit across.
        for y in 1..8 {
            assert_eq!(img.get(1, y), Rgb::ONE);
        }
        assert_eq!(img.get(5, 7), Rgb::ONE);
        assert_eq!(img.get(5, 6), Rgb::ZERO);
        assert_eq!(text_width("L1", 2), 24);
        // Clipped at the border without panicking.
        draw_text(&mut img, 38, 8, "WWW", 3, Rgb::ONE);
    }
}
