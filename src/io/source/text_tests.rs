//! Tests of the text point cloud reader.

use super::*;

fn write(name: &str, text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("temp dir");
    let p = dir.path().join(name);
    std::fs::write(&p, text).expect("write");
    (dir, p)
}

fn message(r: Result<TextSource>) -> String {
    match r {
        Ok(_) => panic!("accepted a malformed file"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn xyz_with_comments_commas_and_normals() {
    let (_d, p) = write(
        "a.xyz",
        "# x y Mean_Curvature nx ny\n\n1,2,3,0,0,1\n4 5 6 0 0 2 # c\r\n",
    );
    let s = TextSource::open_xyz(&p).expect("opens");
    assert_eq!(s.len(), 2);
    assert!(s.has_normals());
    assert_eq!(s.record_length(), 48);
    let mut pts = Vec::new();
    s.for_each_chunk(1, &mut |first, r| {
        pts.push(s.decode(first, r));
        Ok(())
    })
    .expect("streams");
    assert_eq!(pts[1].xyz, [4.0, 5.0, 6.0]);
    assert_eq!(pts[1].normal, Some([0.0, 0.0, 2.0]));
    assert_eq!(
        s.bounds().expect("bounds"),
        [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
    );
}

#[test]
fn pts_count_line_is_skipped() {
    let (_d, p) = write("a.pts", "2\n1 2 3 9\n4 5 6 9\n");
    let s = TextSource::open_xyz(&p).expect("opens");
    assert_eq!(s.len(), 2);
    assert!(!s.has_normals());
    let names: Vec<_> = s.properties().into_iter().map(|p| p.name).collect();
    assert_eq!(names, ["x", "y", "z", "column4"]);
}

#[test]
fn malformed_text_names_the_line() {
    let (_d, p) = write("a.xyz", "1 2 3\n4 5\n");
    assert!(message(TextSource::open_xyz(&p)).contains("line 2: expected 3 values"));
    let (_d, p) = write("a.xyz", "1 2 3\n4 five 6\n");
    assert!(message(TextSource::open_xyz(&p)).contains("line 2: value 2 (y) is \"five\""));
    let (_d, p) = write("a.xyz", "# only a comment\n");
    assert!(message(TextSource::open_xyz(&p)).contains("no points"));
    let (_d, p) = write("a.xyz", "1 2\n");
    assert!(message(TextSource::open_xyz(&p)).contains("line 1: expected at least 3"));
    let (_d, p) = write("a.xyz", "1 2 nan\n");
    assert!(message(TextSource::open_xyz(&p)).contains("line 1: coordinate z is NaN"));
}

#[test]
fn counted_bodies_check_the_count_and_integer_types() {
    let (_d, p) = write("a.txt", "h\n1 2 3 7\n4 5 6 8\n3 0 1\n");
    let body = |count| Body {
        start: 2,
        first_line: 2,
        lines: Lines::Counted {
            skip: 0,
            count,
            noun: "vertices",
        },
    };
    let cols = |ty| {
        let mut c: Vec<_> = ["x", "y", "z"].into_iter().map(Column::f64).collect();
        c.push(Column {
            name: "seg".into(),
            ty,
        });
        c
    };
    let open = |count, ty| {
        TextSource::new(
            &p,
            map_file(&p).expect("map"),
            "t".into(),
            body(count),
            cols(ty),
        )
    };
    assert_eq!(open(2, ScalarType::U8).expect("opens").len(), 2);
    let m = message(open(5, ScalarType::U8));
    assert!(
        m.contains(
            "line 4: expected 4 values (x y z seg) but found 3 (the header declares 5 vertices"
        ),
        "{m}"
    );
    let (_d3, r) = write("c.txt", "h\n1 2 3 7\n4 5 6 8\n");
    let m = message(TextSource::new(
        &r,
        map_file(&r).expect("map"),
        "t".into(),
        body(5),
        cols(ScalarType::U8),
    ));
    assert!(
        m.contains("line 3: the header declares 5 vertices but the file ends after 2"),
        "{m}"
    );
    let (_d2, q) = write("b.txt", "h\n1 2 3 7.5\n");
    let m = message(TextSource::new(
        &q,
        map_file(&q).expect("map"),
        "t".into(),
        body(1),
        cols(ScalarType::U8),
    ));
    assert!(m.contains("line 2: seg is 7.5 but is declared U8"), "{m}");
}

#[test]
fn keyword_lines() {
    let (_d, p) = write("a.obj", "# c\nv 1 2 3\nvn 0 0 1\nf 1 1 1\nv 4 5 6\n");
    let body = Body {
        start: 0,
        first_line: 1,
        lines: Lines::Keyword("v"),
    };
    let lines: Vec<_> = PointLines::new(&map_file(&p).expect("map"), body)
        .map(|(no, c)| (no, tokens(c).count()))
        .collect();
    assert_eq!(lines, [(2, 3), (5, 3)]);
}
